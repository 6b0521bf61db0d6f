"""Generated knee bends imaged with the independent X-ray model, for the tracking benchmarks.

``build_knee_sequence`` (``fluorogui.simulation.knee_bend``) draws each component as a
silhouette that absorbs 62 % of the X-rays, so where the two overlap the edge of the one
behind still shows. Real metal is nearly opaque: behind the other component an outline
is not there at all. ``xray_bend`` writes the same bend (views, poses, project, truth) and
then images every frame again with ``fluorogui.reference.xray`` (Beer-Lambert through both
meshes, soft tissue along the tibia, bone and cement under the tray and about its keel,
the real images' blur, quantum noise; a renderer that shares no code with the matcher),
writing over the PNGs. Used by ``bench_tracking.py --xray``.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from fluorogui.core.projection.pose import pose_to_matrix, transform_points  # noqa: E402


def _frame_images(task) -> list:
    from fluorogui.io.images import write_image
    from fluorogui.reference.xray import MU_METAL, MU_TISSUE, Body, Cylinder, XrayModel, xray_image
    from fluorogui.reference.zone import REAL_BLUR_PX, tray_zone

    views, meshes, poses, paths, seed, index = task
    M = pose_to_matrix(poses["tibial"])
    keel = M[:3, :3] @ meshes["tibial"][0].mean(0) + M[:3, 3]
    model = XrayModel(background=[Cylinder(tuple(keel), tuple(M[:3, 2]), 50.0, MU_TISSUE)],
                      zones=[tray_zone(*meshes["tibial"], M)], detector_blur_px=REAL_BLUR_PX, bits=8)
    bodies = [Body(transform_points(poses[c], meshes[c][0]), meshes[c][1], MU_METAL) for c in ("femoral", "tibial")]
    for k, view in enumerate(views):
        rng = np.random.default_rng([seed, index, k])
        write_image(paths[k], xray_image(view, bodies, model, rng), bits=8)
    return index


def xray_bend(folder: Path, frames: int, *, seed: int = 0, overlap_at_start: bool = True, workers: int = 2) -> Path:
    """A knee bend of the real meshes (``../shared/data/biplane-tka/models``) in ``folder``,
    its images drawn by the X-ray model; returns the project's path."""
    from fluorogui import Session
    from fluorogui.io.meshes.read import load_mesh
    from fluorogui.simulation.knee_bend import build_knee_sequence

    models = ROOT.parent / "shared" / "data" / "biplane-tka" / "models"
    files = {c: models / f"{c}_component.stl" for c in ("femoral", "tibial")}
    path = build_knee_sequence(folder, files["femoral"], files["tibial"], frames=frames, seed=seed,
                               workers=workers, overlap_at_start=overlap_at_start)
    session = Session.open(path)
    meshes = {c: load_mesh(p) for c, p in files.items()}
    truth = session.project.settings["truth"]
    tasks = [(session.views, meshes, {c: np.asarray(p) for c, p in truth[str(f)].items()},
              [seq.paths[i] for seq in session.project.sequences], seed, i)
             for i, f in enumerate(session.frames)]
    if workers > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(workers, multiprocessing.get_context("spawn")) as pool:
            list(pool.map(_frame_images, tasks))
    else:
        for task in tasks:
            _frame_images(task)
    return path
