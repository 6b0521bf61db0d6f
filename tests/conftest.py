"""Shared fixtures: the real data folder beside the repository (skips when absent)."""
from __future__ import annotations

from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
REFERENCE_POSES = Path(__file__).resolve().parent / "data" / "biplane_reference_poses.csv"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data is not present")
    return SHARED_DATA


@pytest.fixture(scope="session")
def biplane(shared_data):
    """The real biplane data: (views, images(frame) -> [cam1, cam2], reference poses by
    (frame, component), prepared meshes by component). Frames are the pairs.csv strings."""
    import csv

    import numpy as np

    from fluorogui.core.projection.mesh import prepare_mesh
    from fluorogui.io.calibration import load_view
    from fluorogui.io.images import read_image
    from fluorogui.io.meshes.read import load_mesh

    d = shared_data / "biplane-tka"
    views = [load_view(d / "calibration" / f"cam{k}_mayacam2.txt") for k in (1, 2)]
    with open(d / "pairs.csv", newline="") as fh:
        pairs = {r["frame"]: r for r in csv.DictReader(fh)}
    keys = ("x", "y", "z", "alpha", "beta", "gamma")
    with open(REFERENCE_POSES, newline="") as fh:
        ref = {(r["frame"], r["component"]): np.array([float(r[k]) for k in keys]) for r in csv.DictReader(fh)}
    meshes = {name: prepare_mesh(*load_mesh(d / "models" / f"{name}_component.stl")) for name in ("femoral", "tibial")}

    def images(frame):
        return [read_image(d / pairs[frame]["cam1"]), read_image(d / pairs[frame]["cam2"])]

    return views, images, ref, meshes
