"""The tibial component on the real biplane data (skips without ../shared/data).

Its keel is a faint edge in bone next to the strong edges of the tray and the femoral
component; these check that the outline follows it (``component_outline``'s gap fill)
and that tracking is not pulled onto the soft-tissue edge beside it."""
import csv
from pathlib import Path

import numpy as np
import pytest

from fluorogui.core.mesh import prepare_mesh
from fluorogui.core.pipeline import match_images
from fluorogui.io.calibration import load_view
from fluorogui.io.images import read_image
from fluorogui.io.meshes import load_mesh

REFERENCE = Path(__file__).resolve().parents[1] / "data" / "biplane_reference_poses.csv"
KEYS = ("x", "y", "z", "alpha", "beta", "gamma")


@pytest.fixture(scope="module")
def real(shared_data):
    d = shared_data / "biplane-tka"
    views = [load_view(d / "calibration" / f"cam{k}_mayacam2.txt") for k in (1, 2)]
    with open(d / "pairs.csv", newline="") as fh:
        pairs = {r["frame"]: r for r in csv.DictReader(fh)}
    with open(REFERENCE, newline="") as fh:
        ref = {r["frame"]: np.array([float(r[k]) for k in KEYS]) for r in csv.DictReader(fh) if r["component"] == "tibial"}
    mesh = prepare_mesh(*load_mesh(d / "models" / "tibial_component.stl"))

    def images(frame):
        return [read_image(d / pairs[frame]["cam1"]), read_image(d / pairs[frame]["cam2"])]

    return views, images, ref, mesh


def check(result, views, expected):
    assert result.converged
    px = [m / v.mm_per_px() for m, v in zip(result.per_view_mean_mm, views)]
    assert max(px) < 0.7, px
    assert np.abs(result.pose[:3] - expected[:3]).max() < 0.15, result.pose - expected
    assert np.abs(result.pose[3:] - expected[3:]).max() < 0.3, result.pose - expected


def test_tibia_frame_0_from_an_offset_start(real):
    views, images, ref, mesh = real
    assert len(ref) >= 10
    pose = ref["0"]
    result, _ = match_images(images("0"), views, mesh, pose + np.array([3.0, -2.0, 2.0, 3.0, -2.0, 2.0]))
    check(result, views, pose)


def test_tibia_tracks_past_the_soft_tissue_edge(real):
    # frame 53 from frame 52's pose: in view 1 the default Canny map misses most of the
    # tibia and its chamfer fit slides onto the skin edge unless the weak edges are used
    views, images, ref, mesh = real
    result, _ = match_images(images("53"), views, mesh, ref["52"])
    check(result, views, ref["53"])
