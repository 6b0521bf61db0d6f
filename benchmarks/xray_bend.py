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


def _frame_images(task) -> int:
    """Draw one frame's images for every noise draw: the costly noise-free part once per view."""
    from fluorogui.io.images import write_image
    from fluorogui.reference.xray import MU_METAL, MU_TISSUE, Body, Cylinder, XrayModel, detector_image, line_integrals
    from fluorogui.reference.zone import REAL_BLUR_PX, tray_zone

    views, meshes, poses, paths, seeds, index = task  # paths: per seed, per view
    M = pose_to_matrix(poses["tibial"])
    keel = M[:3, :3] @ meshes["tibial"][0].mean(0) + M[:3, 3]
    model = XrayModel(background=[Cylinder(tuple(keel), tuple(M[:3, 2]), 50.0, MU_TISSUE)],
                      zones=[tray_zone(*meshes["tibial"], M)], detector_blur_px=REAL_BLUR_PX, bits=8)
    bodies = [Body(transform_points(poses[c], meshes[c][0]), meshes[c][1], MU_METAL) for c in ("femoral", "tibial")]
    for k, view in enumerate(views):
        transmitted = line_integrals(view, bodies, model)
        for seed, per_view in zip(seeds, paths):
            rng = np.random.default_rng([seed, index, k])
            write_image(per_view[k], detector_image(transmitted, model, rng), bits=8)
    return index


def xray_bend(folder: Path, frames: int, *, seed: int = 0, overlap_at_start: bool = True, workers: int = 2) -> Path:
    """A knee bend of the real meshes (``../shared/data/biplane-tka/models``) in ``folder``,
    its images drawn by the X-ray model; returns the project's path."""
    return xray_bends([folder], frames, seeds=[seed], overlap_at_start=overlap_at_start, workers=workers)[0]


def xray_bends(folders: list, frames: int, *, seeds: list, overlap_at_start: bool = True,
               workers: int = 2) -> list[Path]:
    """One bend per (folder, seed), as ``xray_bend`` draws each alone (the same images). The
    seed only draws the noise (the motion and the views do not depend on it), so the
    Beer-Lambert path lengths, nearly all the cost, are computed once for all the seeds."""
    from fluorogui import Session
    from fluorogui.io.meshes.read import load_mesh
    from fluorogui.simulation.knee_bend import build_knee_sequence

    models = ROOT.parent / "shared" / "data" / "biplane-tka" / "models"
    files = {c: models / f"{c}_component.stl" for c in ("femoral", "tibial")}
    paths = [build_knee_sequence(Path(folder), files["femoral"], files["tibial"], frames=frames, seed=seed,
                                 workers=workers, overlap_at_start=overlap_at_start)
             for folder, seed in zip(folders, seeds, strict=True)]
    sessions = [Session.open(path) for path in paths]
    first = sessions[0]
    for other in sessions[1:]:  # what is shared must be the same
        if other.project.settings["truth"] != first.project.settings["truth"] or \
                [v.to_dict() for v in other.views] != [v.to_dict() for v in first.views]:
            raise ValueError("the bends differ in more than their noise: they cannot share their path lengths")
    meshes = {c: load_mesh(p) for c, p in files.items()}
    truth = first.project.settings["truth"]
    tasks = [(first.views, meshes, {c: np.asarray(p) for c, p in truth[str(f)].items()},
              [[seq.paths[i] for seq in s.project.sequences] for s in sessions], list(seeds), i)
             for i, f in enumerate(first.frames)]
    if workers > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(workers, multiprocessing.get_context("spawn")) as pool:
            list(pool.map(_frame_images, tasks))
    else:
        for task in tasks:
            _frame_images(task)
    return paths
