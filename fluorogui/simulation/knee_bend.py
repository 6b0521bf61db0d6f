"""A generated two-view knee-bend sequence with exactly known poses: the tracking benchmark.

``build_knee_sequence(directory, femoral_mesh, tibial_mesh)`` renders any pair of implant
meshes (the real ones: ``data/biplane-tka/models/*.stl``) through a knee bend and writes a
session the app, the command line and the benchmarks open like real data:

* ``calibration/cam1.json``, ``cam2.json``: two views 65 degrees apart (not orthogonal).
  cam1 is near-lateral and looks up at the knee from 12 degrees below the horizontal, so
  in its image the near rim of the tibial tray rises over the far femoral condyle: the
  two silhouettes overlap in every frame (with the real meshes 1600-3100 px at 1024 px).
  cam2 is an anterolateral oblique, 3 degrees from above, turned 2 degrees about its
  beam. Source-intensifier distances 1100 and 1250 mm, pixel pitch 0.3 mm at 1024 px
  (the field of view is the same at any ``image_size``), principal points 10-20 px off
  centre. Both components stay inside the circular intensifier field (with the real
  meshes at least 148 px from its rim);
* ``cam1/``, ``cam2/``: one PNG per frame (8-bit unless ``bits=16``), numbered
  ``start_frame ..``; ``pairs.csv`` (``frame,cam1,cam2``), so
  ``fluorogui.io.importer.detect_biplane_folder`` recognises the folder;
* ``knee_bend.fluoro``: the project. Its models point at the given mesh files (not
  copied). No poses: tracking starts from nothing or from a find. ``settings["truth"]``
  holds the true poses ``{"<frame>": {"femoral": [x, y, z, a, b, g], "tibial": [...]}}``
  (the exact floats the images were rendered from; JSON keeps every bit), and
  ``settings["synthetic"]`` the recipe, the per-frame flexion, the silhouette overlap per
  view and frame, and the smallest margin to the intensifier field.

The image model is the demo's (``fluorogui.simulation.demo.xray_image``): each component's
exact silhouette (8 x 8 samples per pixel through ``fluorogui.simulation.render.coverage_of_meshes``,
a rasteriser independent of the matcher's silhouette code) absorbs 62 % of the X-rays,
and transmissions multiply, so where the components overlap the image is darker still,
as behind two metal parts; blurred bone and soft tissue, focal-spot blur, a circular
intensifier field and noise. ``metal_coverage`` computes the same coverage as
``coverage_of_meshes`` in a fraction of the time (see there); the smooth background,
tissue and bone are computed on a 2x coarser grid.

The motion (``knee_bend_truth``) assumes the component frames of the real meshes:
x mediolateral, y anterior, z proximal, right-handed, so +x points to the patient's
right, the lateral side of a right knee (the real femoral component's anterior flange
rises higher on +x, as a lateral flange does); origins: the femoral one about 26 mm
above the distal condyles, the tibial one on the tray top (its highest z). The tibia
stands almost upright and tilts forward with the flexion (shank 3 -> 35 deg), moving
24 mm forwards and 10 mm down and swaying a little on its own. The femur flexes 0 -> 100
deg relative to the tibia about its mediolateral axis; its origin rolls back 10 mm, the
tibia rotates internally by up to 10 deg, the knee goes into up to 2 deg of varus, and
the femoral lowest point stays ``GAP_MM`` above the tray top (where the polyethylene
insert, invisible in X-ray, would be). The speed varies: slow at the start, a first bend
to 40 deg, a near pause (40 -> 41.5 deg over 16 frames of 100), a burst to 94.5 deg at
up to 3.6 deg per frame, and a slow settle to 100 deg.

``side="left"`` mirrors the motion and the views through the sagittal plane (x -> -x):
x translations, varus/valgus and internal/external rotations change sign and the
sources stand on the mirrored side. The meshes are used as given (they cannot be
mirrored without changing the files), so a right component then moves as a left knee.
"""
from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path

import cv2
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.pose import matrix_to_pose, rotation_matrix, transform_points
from fluorogui.core.records import ImageSequence, ModelEntry, Project
from fluorogui.io.calibration import save_view_json
from fluorogui.io.errors import InputError, describe_os_error
from fluorogui.io.images import write_image
from fluorogui.io.meshes.read import load_mesh
from fluorogui.io.project.document import save_project
from fluorogui.simulation.demo import (
    FIELD_RADIUS_FRACTION,
    SUPERSAMPLE,
    ViewSpec,
    anatomy_meshes,
    posed_anatomy,
    views_from_specs,
    write_pairs_csv,
    xray_image,
)
from fluorogui.simulation.render import coverage_of_meshes

#: Bump when anything the recipe writes changes.
RECIPE_VERSION = 1
PROJECT_NAME = "knee_bend.fluoro"
COMPONENTS = ("femoral", "tibial")
CAMERA_FOLDERS = ("cam1", "cam2")
SIDES = ("right", "left")

# The fluoroscope, for a right knee (see ``sequence_views``). Both aim at the world origin.
VIEW_SPECS = (
    # near-lateral (source on the lateral side, slightly posterior), looking up 12 deg
    ViewSpec("cam1", azimuth_deg=165.0, elevation_deg=12.0, source_to_image_mm=1100.0,
             source_to_target_mm=820.0, pitch_mm=0.3, principal_offset_px=(14.0, -9.5)),
    # anterolateral oblique, 3 deg from above, image turned 2 deg about the beam
    ViewSpec("cam2", azimuth_deg=229.0, elevation_deg=-3.0, source_to_image_mm=1250.0,
             source_to_target_mm=960.0, pitch_mm=0.3, principal_offset_px=(-11.0, 17.5), roll_deg=2.0),
)
OVERLAP_VIEW = "cam1"
#: ``overlap_at_start``: cam1 looks down at the knee from this elevation instead, so the femoral
#: condyles cover the tray's far rim most at extension (with the real meshes ~7800 px of overlap
#: at 1024 px in the first frames, ~1600 px at the end): the hardest frames come first
START_OVERLAP_ELEVATION_DEG = -20.0
SOFT_DOWNSAMPLE = 2  # background, tissue and bone on a 2x coarser grid (they are smooth)
BAND_TILE_PX = 48  # tiles of the silhouette border rendered at full supersampling (metal_coverage)

# The knee bend.
FLEXION_RANGE_DEG = (0.0, 100.0)
GAP_MM = 9.0  # femoral lowest point above the tibial tray top: the insert
#: Speed profile: (start, end, share of the flexion range) of sin^2 bursts of flexion speed
#: over normalised time; between and at their ends the knee is (nearly) still.
SPEED_PHASES = ((0.00, 0.42, 0.400), (0.42, 0.58, 0.015), (0.58, 0.88, 0.530), (0.88, 1.00, 0.055))
TIBIA_START_MM = (0.0, -12.0, -16.0)  # tibial origin (tray top) at frame 0, world mm


# -- public API -------------------------------------------------------------------------------
def build_knee_sequence(directory, femoral_mesh, tibial_mesh, *, frames: int = 100, image_size: int = 1024,
                        seed: int = 0, side: str = "right", start_frame: int = 0, bits: int = 8,
                        workers: int = 1, drift_mm=(0.0, 0.0, 0.0), overlap_at_start: bool = False) -> Path:
    """Write a generated two-view knee-bend sequence into `directory`; return the .fluoro project path.

    ``drift_mm`` (world x, y, z) moves the whole knee by that much over the sequence
    (linearly in time), e.g. out of an intensifier's field of view. ``overlap_at_start``:
    cam1 looks down from ``START_OVERLAP_ELEVATION_DEG`` so the components overlap most in
    its first frames (tracking meets its hardest frames before it has any motion to go on).
    ``bits``: 8 or 16-bit PNG images. ``workers`` > 1 renders the frames in that many
    processes (the images are the same: each one has its own random stream). The workers
    are spawned, so a script that asks for them must call this under
    ``if __name__ == "__main__":``. 100 frames of 1024 x 1024 take about 30 s of CPU.
    """
    if frames < 1:
        raise ValueError("the sequence needs at least one frame")
    if image_size < 64:
        raise ValueError("the images need at least 64 x 64 pixels")
    if side not in SIDES:
        raise ValueError(f"side must be 'right' or 'left', not {side!r}")
    if bits not in (8, 16):
        raise ValueError("bits must be 8 or 16")
    directory = Path(directory).absolute()
    mesh_paths = {"femoral": Path(femoral_mesh).absolute(), "tibial": Path(tibial_mesh).absolute()}
    meshes = {c: load_mesh(p) for c, p in mesh_paths.items()}
    try:
        for sub in ("calibration", *CAMERA_FOLDERS):
            (directory / sub).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(directory, f"cannot create the sequence folder: {describe_os_error(exc)}") from None

    views = sequence_views(image_size, side, overlap_at_start=overlap_at_start)
    for view in views:
        save_view_json(view, directory / "calibration" / f"{view.name}.json")
    flexion = flexion_schedule(frames)
    truth = knee_bend_truth(meshes["femoral"][0], meshes["tibial"][0], flexion, side)
    drift = np.asarray(drift_mm, dtype=float).reshape(3)
    for i, poses in enumerate(truth):
        for pose in poses.values():
            pose[:3] += drift * (i / max(frames - 1, 1))
    frame_numbers = [start_frame + i for i in range(frames)]

    sequences = [ImageSequence([directory / v.name / f"frame_{f:04d}.png" for f in frame_numbers]) for v in views]
    scene = _Scene(views, meshes, truth, [s.paths for s in sequences], seed, bits)
    if workers > 1 and frames > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # spawned, not forked: safe from a process that runs threads (the app)
        with ProcessPoolExecutor(min(workers, frames), multiprocessing.get_context("spawn"),
                                 initializer=_set_scene, initargs=(scene,)) as pool:
            stats = [row for part in pool.map(_render_frames, np.array_split(np.arange(frames), workers))
                     for row in part]
    else:
        _set_scene(scene)
        try:
            stats = _render_frames(range(frames))
        finally:
            _SCENE.clear()
    overlap = {v.name: [row[0][k] for row in stats] for k, v in enumerate(views)}
    radius = FIELD_RADIUS_FRACTION * image_size
    margin = {v.name: round(radius - max(row[1][k] for row in stats), 2) for k, v in enumerate(views)}
    write_pairs_csv(directory / "pairs.csv", frame_numbers, sequences, directory)

    steps = np.abs(np.diff(flexion)) if frames > 1 else np.zeros(1)
    project = Project(
        views=views,
        sequences=sequences,
        frames=frame_numbers,
        models=[ModelEntry(c, mesh_paths[c]) for c in COMPONENTS],
        poses={},
        settings={
            "truth": {str(f): {c: [float(x) for x in truth[i][c]] for c in COMPONENTS}
                      for i, f in enumerate(frame_numbers)},
            "synthetic": {
                "recipe_version": RECIPE_VERSION,
                "kind": "knee bend",
                "seed": int(seed),
                "side": side,
                "frames": int(frames),
                "start_frame": int(start_frame),
                "image_size": int(image_size),
                "bits": int(bits),
                "meshes": {c: {"path": str(mesh_paths[c]), "sha256": _sha256(mesh_paths[c])} for c in COMPONENTS},
                "views": [_spec_summary(spec) for spec in _side_specs(side, overlap_at_start)],
                "gap_mm": GAP_MM,
                "drift_mm": [float(x) for x in drift],
                "overlap_at_start": bool(overlap_at_start),
                "flexion_deg": [float(x) for x in flexion],
                "flexion_step_deg": [float(steps.min()), float(steps.max())],
                "overlap_view": OVERLAP_VIEW,
                "overlap_px": overlap,
                "field_margin_px": margin,
            },
        },
    )
    project_path = directory / PROJECT_NAME
    save_project(project, project_path)
    return project_path


def sequence_views(image_size: int = 1024, side: str = "right", *, overlap_at_start: bool = False) -> list[View]:
    """The two views of the sequence (``VIEW_SPECS``, mirrored for a left knee; cam1 looking
    down from ``START_OVERLAP_ELEVATION_DEG`` with ``overlap_at_start``)."""
    return views_from_specs(_side_specs(side, overlap_at_start), image_size)


def flexion_schedule(frames: int) -> np.ndarray:
    """Flexion (deg) of each frame: ``FLEXION_RANGE_DEG`` traversed at the ``SPEED_PHASES`` speeds."""
    s = np.linspace(0.0, 1.0, frames) if frames > 1 else np.zeros(1)
    done = np.zeros_like(s)
    for start, end, share in SPEED_PHASES:
        x = np.clip((s - start) / (end - start), 0.0, 1.0)
        done += share * (x - np.sin(2.0 * np.pi * x) / (2.0 * np.pi))  # integral of 2 sin^2(pi x)
    total = sum(share for _, _, share in SPEED_PHASES)
    low, high = FLEXION_RANGE_DEG
    return low + (high - low) * done / total


def knee_bend_truth(femoral_vertices, tibial_vertices, flexion_deg, side: str = "right") -> list[dict]:
    """True poses ``[{component: (x, y, z, alpha, beta, gamma)}]``, one per flexion angle.

    The femur's height over the tibia is solved from the femoral vertices so that its
    lowest point (in the tibial frame) is ``GAP_MM`` above the highest tibial vertex.
    Time (the frame's place in the sequence) drives a small sway of the tibia, so the
    knee is never perfectly still.
    """
    if side not in SIDES:
        raise ValueError(f"side must be 'right' or 'left', not {side!r}")
    femoral_vertices = np.asarray(femoral_vertices, dtype=float)
    tray_top = float(np.asarray(tibial_vertices, dtype=float)[:, 2].max())
    m = 1.0 if side == "right" else -1.0  # the sign of everything mediolateral
    flexion_deg = np.asarray(flexion_deg, dtype=float)
    n = len(flexion_deg)
    low, high = FLEXION_RANGE_DEG
    out = []
    for i, flexion in enumerate(flexion_deg):
        p = (flexion - low) / (high - low)  # progress of the bend
        t = i / max(n - 1, 1)  # progress in time
        sway = np.sin(2.0 * np.pi * t / 0.55), np.sin(2.0 * np.pi * t / 0.8 + 1.0)
        tibia = np.eye(4)  # the leg turns about its long axis, leans sideways, the shank tilts forward
        tibia[:3, :3] = (rotation_matrix(0.0, 0.0, m * (5.0 - 9.0 * p + 1.0 * sway[1]))
                         @ rotation_matrix(0.0, m * (1.0 + 1.5 * p), 0.0)
                         @ rotation_matrix(-(3.0 + 32.0 * p), 0.0, 0.0))
        x0, y0, z0 = TIBIA_START_MM
        tibia[:3, 3] = [m * (x0 + 3.0 * p + 0.8 * sway[0]), y0 + 24.0 * p + 0.6 * sway[1], z0 - 10.0 * p * p]
        relative = np.eye(4)  # the femur in the tibial frame
        relative[:3, :3] = (rotation_matrix(0.0, 0.0, -m * (1.5 + 8.5 * p))  # tibial internal rotation
                            @ rotation_matrix(0.0, -m * (0.5 + 1.5 * np.sin(np.pi * p)), 0.0)  # varus
                            @ rotation_matrix(flexion, 0.0, 0.0))
        lowest = float((femoral_vertices @ relative[2, :3]).min())
        relative[:3, 3] = [m * (0.5 + 1.0 * p), 1.0 - 10.0 * p, tray_top + GAP_MM - lowest]  # rollback
        poses = {"tibial": matrix_to_pose(tibia), "femoral": matrix_to_pose(tibia @ relative)}
        out.append({c: np.array([float(x) for x in poses[c]]) for c in COMPONENTS})
    return out


def metal_coverage(view: View, vertices_world, faces, topology: "MeshTopology | None" = None) -> np.ndarray:
    """The silhouette coverage (H, W) of one mesh: ``coverage_of_meshes(view, [mesh], 8)``, faster.

    Only the faces that make up the silhouette are rasterised: those turned to the source
    (every ray through the silhouette of a closed, consistently oriented mesh enters it
    through one) and, near a hole of an open mesh, all faces (any patch closing the hole
    projects within the bounding box of the hole's vertices). Each pixel first gets one
    sample at its centre. The silhouette's border lies on the projected contour edges
    (between a face turned to the source and one turned away, or on a hole); pixels on
    them (widened by 2 px) and within 3 px of a change of the one-sample image, or outside
    it, are redone with the full 8 x 8 samples, in ``BAND_TILE_PX`` tiles through views
    cropped to them. Every other pixel is wholly inside or outside the silhouette. The one
    case this misses is a gap in the silhouette narrower than a pixel reaching more than
    3 px into it without uncovering a pixel centre; on the real implant meshes the result
    equals ``coverage_of_meshes`` in every image of the sequence (checked, and tested on
    some). Meshes that are not consistently oriented, or reach behind the source, are
    rendered with ``coverage_of_meshes`` directly.
    """
    vertices_world = np.asarray(vertices_world, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    topology = topology or MeshTopology.of(vertices_world, faces)
    if topology.orientation == 0 or np.any((vertices_world - view.source) @ view.normal <= 0.0):
        return coverage_of_meshes(view, [(vertices_world, faces)], SUPERSAMPLE)
    full = view
    uv = full.project(vertices_world)
    # work in the window of the image the mesh projects into (with a margin)
    c0_w, r0_w = np.maximum(np.floor(uv.min(axis=0)).astype(np.int64) - 4, 0)
    c1_w, r1_w = np.minimum(np.ceil(uv.max(axis=0)).astype(np.int64) + 5, full.image_size)
    result = np.zeros((full.image_size[1], full.image_size[0]))
    if c0_w >= c1_w or r0_w >= r1_w:
        return result
    view = _window(full, int(c0_w), int(r0_w), int(c1_w), r1=int(r1_w))
    width, height = view.image_size
    uv = uv - (c0_w, r0_w)
    tri = uv[faces]
    area = ((tri[:, 1, 0] - tri[:, 0, 0]) * (tri[:, 2, 1] - tri[:, 0, 1])
            - (tri[:, 1, 1] - tri[:, 0, 1]) * (tri[:, 2, 0] - tri[:, 0, 0]))
    handed = np.sign(np.cross(view.e_u, view.e_v) @ view.normal)  # +1 for a right-handed image frame
    front = area * (handed * topology.orientation) < 0.0
    keep = front.copy()
    lo = np.minimum(np.minimum(tri[:, 0], tri[:, 1]), tri[:, 2])
    hi = np.maximum(np.maximum(tri[:, 0], tri[:, 1]), tri[:, 2])
    for group in topology.holes:
        h_lo, h_hi = uv[group].min(axis=0) - 1.0, uv[group].max(axis=0) + 1.0
        keep |= (hi[:, 0] >= h_lo[0]) & (hi[:, 1] >= h_lo[1]) & (lo[:, 0] <= h_hi[0]) & (lo[:, 1] <= h_hi[1])
    coverage = coverage_of_meshes(view, [(vertices_world, faces[keep])], 1)

    # the band: pixels the contour edges pass through (sampled every <= 0.5 px), widened
    f0, f1 = topology.edge_faces[:, 0], topology.edge_faces[:, 1]
    has_two = f1 >= 0
    f1 = np.maximum(f1, 0)
    inner = ~topology.irregular & front[f0] & front[f1]
    contour = topology.edges[(keep[f0] | (has_two & keep[f1])) & ~inner]
    if len(contour) == 0:
        result[r0_w:r1_w, c0_w:c1_w] = coverage
        return result
    a, b = uv[contour[:, 0]], uv[contour[:, 1]]
    steps = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) / 0.5).astype(np.int64), 1)
    owner = np.repeat(np.arange(len(contour)), steps + 1)
    t = (np.arange(owner.size) - np.repeat(np.cumsum(steps + 1) - (steps + 1), steps + 1)) / steps[owner]
    samples = np.rint(a[owner] + (b - a)[owner] * t[:, None]).astype(np.int64)
    on_image = (samples[:, 0] >= 0) & (samples[:, 0] < width) & (samples[:, 1] >= 0) & (samples[:, 1] < height)
    band = np.zeros((height, width), dtype=np.uint8)
    band[samples[on_image, 1], samples[on_image, 0]] = 1
    band = cv2.dilate(band, np.ones((5, 5), np.uint8)).astype(bool)
    # ... where the one-sample image changes nearby or is empty (contour edges deep inside are hidden)
    mask = (coverage > 0).astype(np.uint8)
    change = cv2.morphologyEx(mask, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8))
    band &= cv2.dilate(change, np.ones((7, 7), np.uint8)).astype(bool) | (mask == 0)

    # faces that reach a band pixel (their pixel bounding box holds one), binned into tiles
    kept = faces[keep]
    c_lo = np.clip(np.floor(lo[keep, 0]).astype(np.int64), 0, width - 1)
    r_lo = np.clip(np.floor(lo[keep, 1]).astype(np.int64), 0, height - 1)
    c_hi = np.clip(np.ceil(hi[keep, 0]).astype(np.int64), 0, width - 1)
    r_hi = np.clip(np.ceil(hi[keep, 1]).astype(np.int64), 0, height - 1)
    counts = cv2.integral(band.astype(np.uint8))  # (H + 1, W + 1) sums of band pixels
    reach = counts[r_hi + 1, c_hi + 1] - counts[r_lo, c_hi + 1] - counts[r_hi + 1, c_lo] + counts[r_lo, c_lo] > 0
    tile = BAND_TILE_PX
    per_row = (width + tile - 1) // tile
    t_c0, t_c1, t_r0, t_r1 = c_lo[reach] // tile, c_hi[reach] // tile, r_lo[reach] // tile, r_hi[reach] // tile
    spread = (t_c1 - t_c0 + 1) * (t_r1 - t_r0 + 1)  # tiles each face's box meets
    face = np.repeat(np.arange(len(spread)), spread)
    k = np.arange(face.size) - np.repeat(np.cumsum(spread) - spread, spread)
    span = (t_c1 - t_c0 + 1)[face]
    tile_of = (t_r0[face] + k // span) * per_row + t_c0[face] + k % span
    order = np.argsort(tile_of, kind="stable")
    tile_of, face = tile_of[order], face[order]
    bounds = np.flatnonzero(np.diff(tile_of)) + 1
    soup_all = vertices_world[kept[reach]]  # (F, 3, 3)
    for group in np.split(np.arange(tile_of.size), bounds):
        index = int(tile_of[group[0]])
        r0, c0 = (index // per_row) * tile, (index % per_row) * tile
        r1, c1 = min(r0 + tile, height), min(c0 + tile, width)
        here = band[r0:r1, c0:c1]
        if not here.any():
            continue
        soup = soup_all[face[group]].reshape(-1, 3)
        fine = coverage_of_meshes(_window(view, c0, r0, c1, r1=r1), [(soup, np.arange(len(soup)).reshape(-1, 3))],
                                  SUPERSAMPLE)
        coverage[r0:r1, c0:c1][here] = fine[here]
    window = (slice(int(r0_w), int(r1_w)), slice(int(c0_w), int(c1_w)))
    result[window] = coverage
    return result


def _window(view: View, c0: int, r0: int, c1: int, *, r1: int) -> View:
    """The view of the pixels [r0, r1) x [c0, c1) of ``view``'s image (same projection)."""
    cx, cy = view.principal_point
    return dataclasses.replace(view, image_size=(c1 - c0, r1 - r0), principal_point=(cx - c0, cy - r0))


@dataclasses.dataclass(frozen=True)
class MeshTopology:
    """Edges of a triangle mesh with their faces, for ``metal_coverage``.

    ``edges`` (E, 2) vertex indices; ``edge_faces`` (E, 2) the first two faces of each
    edge (-1 when it has only one); ``irregular`` (E,) edges not shared by exactly two
    faces; ``holes``: the vertex indices of each connected set of irregular edges;
    ``orientation``: +1 when the faces are consistently ordered counter-clockwise seen
    from outside, -1 when clockwise, 0 when not consistent.
    """

    edges: np.ndarray
    edge_faces: np.ndarray
    irregular: np.ndarray
    holes: tuple
    orientation: int

    @classmethod
    def of(cls, vertices, faces) -> "MeshTopology":
        faces = np.asarray(faces, dtype=np.int64)
        directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
        forward = directed[:, 0] < directed[:, 1]
        pairs = np.sort(directed, axis=1)
        owner = np.tile(np.arange(len(faces)), 3)
        order = np.lexsort((pairs[:, 1], pairs[:, 0]))
        pairs, owner, forward = pairs[order], owner[order], forward[order]
        first = np.ones(len(pairs), dtype=bool)
        first[1:] = np.any(pairs[1:] != pairs[:-1], axis=1)
        start = np.flatnonzero(first)
        counts = np.diff(np.append(start, len(pairs)))
        following = np.minimum(start + 1, len(pairs) - 1)
        second = np.where(counts >= 2, owner[following], -1)
        edges = pairs[start]
        irregular = counts != 2
        # two faces ordered alike run along their shared edge in opposite directions
        orientation = 0
        if np.all(forward[start][~irregular] != forward[following][~irregular]):
            tri = np.asarray(vertices, dtype=float)[faces]
            volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()
            orientation = 1 if volume > 0 else -1
        holes = ()
        if irregular.any():
            nodes, index = np.unique(edges[irregular], return_inverse=True)
            index = index.reshape(-1, 2)
            graph = coo_matrix((np.ones(len(index)), (index[:, 0], index[:, 1])), shape=(len(nodes), len(nodes)))
            count, labels = connected_components(graph, directed=False)
            holes = tuple(nodes[labels == label] for label in range(count))
        return cls(edges, np.column_stack([owner[start], second]), irregular, holes, orientation)


# -- helpers ----------------------------------------------------------------------------------
@dataclasses.dataclass
class _Scene:
    """What rendering a frame needs (sent once to each worker process)."""

    views: list
    meshes: dict
    truth: list
    paths: list  # per view, per frame
    seed: int
    bits: int


_SCENE: dict = {}


def _set_scene(scene: _Scene) -> None:
    _SCENE["scene"] = scene
    _SCENE["topology"] = {c: MeshTopology.of(v, f) for c, (v, f) in scene.meshes.items()}
    _SCENE["anatomy"] = anatomy_meshes()


def _render_frames(indices) -> list:
    """Render and write the images of frames ``indices`` (positions in the sequence).

    Per frame: the overlap of the two silhouettes (pixels covered by both) and the largest
    distance of a projected vertex from the image centre, per view.
    """
    scene, topology, anatomy = _SCENE["scene"], _SCENE["topology"], _SCENE["anatomy"]
    stats = []
    for i in indices:
        i = int(i)
        world = {c: transform_points(scene.truth[i][c], scene.meshes[c][0]) for c in COMPONENTS}
        soft = posed_anatomy(scene.truth[i], anatomy)
        overlap, reach = [], []
        for k, view in enumerate(scene.views):
            coverages = [metal_coverage(view, world[c], scene.meshes[c][1], topology[c]).astype(np.float32)
                         for c in COMPONENTS]
            rng = np.random.default_rng([scene.seed, i, k])  # one stream per image: any frame can be redone alone
            image = xray_image(view, coverages, soft, rng, soft_downsample=SOFT_DOWNSAMPLE)
            write_image(scene.paths[k][i], image, bits=scene.bits)
            overlap.append(int(round(float(np.minimum(*coverages).sum()))))
            centre = (np.asarray(view.image_size) - 1) / 2.0
            reach.append(max(float(np.linalg.norm(view.project(w) - centre, axis=1).max()) for w in world.values()))
        stats.append((overlap, reach))
    return stats


def _side_specs(side: str, overlap_at_start: bool = False) -> list[ViewSpec]:
    specs = [dataclasses.replace(spec, elevation_deg=START_OVERLAP_ELEVATION_DEG)
             if overlap_at_start and spec.name == OVERLAP_VIEW else spec for spec in VIEW_SPECS]
    if side == "right":
        return specs
    # mirror x -> -x: the beam's azimuth theta becomes 180 - theta; the roll turns the other way
    return [dataclasses.replace(spec, azimuth_deg=180.0 - spec.azimuth_deg, roll_deg=-spec.roll_deg)
            for spec in specs]


def _spec_summary(spec: ViewSpec) -> dict:
    return {
        "name": spec.name,
        "azimuth_deg": spec.azimuth_deg,
        "elevation_deg": spec.elevation_deg,
        "roll_deg": spec.roll_deg,
        "source_to_image_mm": spec.source_to_image_mm,
        "source_to_isocentre_mm": spec.source_to_target_mm,
        "pitch_mm_at_1024px": spec.pitch_mm,
        "principal_offset_px_at_1024px": list(spec.principal_offset_px),
    }


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


__all__ = ["RECIPE_VERSION", "VIEW_SPECS", "MeshTopology", "build_knee_sequence", "flexion_schedule",
           "knee_bend_truth", "metal_coverage", "sequence_views"]
