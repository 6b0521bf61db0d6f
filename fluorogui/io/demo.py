"""The demo project: a complete, generated biplane session to try the app without data.

``build_demo_project(directory)`` writes, from nothing but code:

* ``models/femoral_component.stl`` and ``models/tibial_component.stl``: the procedural
  implant phantoms of ``fluorogui.core.phantoms`` (mm);
* ``calibration/cam1.json`` and ``cam2.json``: two views ~65 degrees apart, both
  near-lateral to the knee as in a biplane set-up, source-intensifier distance 1200 mm,
  pixel pitch 0.3 mm, 1024x1024 px, principal points slightly off centre;
* ``cam1/`` and ``cam2/``: one 8-bit PNG per frame of a knee bend (flexion 10 -> 40 deg
  with femoral rollback and a forward-tilting shank). Both components are rendered
  together (their silhouettes may overlap) as dark metal over blurred bone and soft
  tissue, on a shaded, noisy background inside a circular intensifier field;
* ``pairs.csv`` (``frame,cam1,cam2``), so the folder also imports through
  ``fluorogui.io.importer.detect_biplane_folder``;
* ``demo.fluoro``: the project, with the true poses in ``settings["demo_truth"]``
  (``{"frame": {"femoral": [x, y, z, a, b, g], "tibial": [...]}}``, string frame keys as
  JSON needs) and a rough starting pose (truth plus a few mm / deg) for the first frame.

World frame: origin near the joint centre, +z up, +x mediolateral, +y anterior. The
component frames are those of the phantoms (x ML, y AP, z proximal).

``demo_project_path(cache_dir)`` returns a cached build when its recipe stamp matches
``RECIPE_VERSION`` and the build arguments, otherwise builds into a temporary folder and
swaps it in. Bump ``RECIPE_VERSION`` whenever the output of the recipe changes.
"""
from __future__ import annotations

import csv
import dataclasses
import functools
import io
import json
import os
import shutil
import tempfile
from pathlib import Path

import cv2
import numpy as np

from fluorogui.core.geometry import View
from fluorogui.core.phantoms import femoral_component_mesh, tibial_component_mesh
from fluorogui.core.pose import matrix_to_pose, rotation_matrix, transform_points
from fluorogui.core.render import coverage_of_meshes, shaded_background
from fluorogui.core.session import ImageSequence, ModelEntry, PoseRecord, Project
from fluorogui.io.calibration import save_view_json
from fluorogui.io.errors import InputError, atomic_write_text, describe_os_error
from fluorogui.io.images import write_image
from fluorogui.io.project import load_project, save_project

#: Bump when anything the recipe writes changes, so cached demos are rebuilt.
RECIPE_VERSION = 2
PROJECT_NAME = "demo.fluoro"
STAMP_NAME = "recipe.json"
COMPONENTS = ("femoral", "tibial")
MODEL_FILES = {"femoral": "femoral_component.stl", "tibial": "tibial_component.stl"}
CAMERA_FOLDERS = ("cam1", "cam2")

# Set-up of the virtual biplane fluoroscope.
SOURCE_TO_IMAGE_MM = 1200.0
SOURCE_TO_ISOCENTRE_MM = 950.0
PITCH_MM = 0.3
VIEW_AZIMUTHS_DEG = (-32.5, 32.5)  # beam directions about +z, measured from +x: 65 deg apart
VIEW_ELEVATIONS_DEG = (4.0, -3.0)
PRINCIPAL_OFFSETS_PX = ((3.4, -2.1), (-1.7, 4.2))

# Motion of the knee bend.
FLEXION_RANGE_DEG = (10.0, 40.0)
INSERT_MM = 41.0  # femoral origin (condylar arc centre) above the tibial tray top
START_OFFSET_RANGE = (1.0, 3.0)  # |start - truth| per DOF, mm and deg

# Image model (intensities in [0, 1]).
SUPERSAMPLE = 8
IMPLANT_CONTRAST = 0.62  # fraction of the X-rays each structure absorbs
BONE_CONTRAST = 0.16
TISSUE_CONTRAST = 0.22
NOISE_SD = 0.025
FIELD_RADIUS_FRACTION = 0.485  # circular intensifier field, of the image size


# -- public API ---------------------------------------------------------------------------
def build_demo_project(directory, frames: int = 4, image_size: int = 1024, seed: int = 0) -> Path:
    """Write the demo session into ``directory`` (created if needed); return the .fluoro path."""
    if frames < 1:
        raise ValueError("the demo needs at least one frame")
    if image_size < 64:
        raise ValueError("the demo images need at least 64 x 64 pixels")
    directory = Path(directory).absolute()
    rng = np.random.default_rng(seed)
    try:
        for sub in ("models", "calibration", *CAMERA_FOLDERS):
            (directory / sub).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(directory, f"cannot create the demo folder: {describe_os_error(exc)}") from None

    meshes = {"femoral": femoral_component_mesh(), "tibial": tibial_component_mesh()}
    models = []
    for component in COMPONENTS:
        path = directory / "models" / MODEL_FILES[component]
        write_stl(path, *meshes[component])
        models.append(ModelEntry(component, path))
    # what the app will read back is float32: render exactly that
    meshes = {c: (v.astype(np.float32).astype(float), f) for c, (v, f) in meshes.items()}

    views = demo_views(image_size)
    for view, folder in zip(views, CAMERA_FOLDERS):
        save_view_json(view, directory / "calibration" / f"{folder}.json")

    flexions = np.linspace(*FLEXION_RANGE_DEG, frames)  # one frame: the first angle
    frame_numbers = list(range(frames))
    truth = {f: knee_bend_poses(flex, (f / max(frames - 1, 1))) for f, flex in zip(frame_numbers, flexions)}
    anatomy = _anatomy_meshes()
    sequences = [ImageSequence() for _ in views]
    for frame in frame_numbers:
        posed = [(transform_points(truth[frame][c], meshes[c][0]), meshes[c][1]) for c in COMPONENTS]
        soft = {name: (transform_points(truth[frame][c], v), f) for name, (c, v, f) in anatomy.items()}
        for k, view in enumerate(views):
            image = _render_view(view, posed, soft, rng)
            path = directory / CAMERA_FOLDERS[k] / f"frame_{frame:03d}.png"
            write_image(path, image)
            sequences[k].paths.append(path)

    _write_pairs_csv(directory / "pairs.csv", frame_numbers, sequences, directory)

    poses = {}
    signs = rng.choice([-1.0, 1.0], size=(len(COMPONENTS), 6))
    sizes = rng.uniform(*START_OFFSET_RANGE, size=(len(COMPONENTS), 6))
    for i, component in enumerate(COMPONENTS):
        poses[(frame_numbers[0], component)] = PoseRecord(truth[frame_numbers[0]][component] + signs[i] * sizes[i])
    project = Project(
        views=views,
        sequences=sequences,
        frames=frame_numbers,
        models=models,
        poses=poses,
        settings={
            "demo_truth": {
                str(f): {c: [round(float(x), 9) for x in truth[f][c]] for c in COMPONENTS} for f in frame_numbers
            },
            "demo": {
                "recipe_version": RECIPE_VERSION,
                "seed": int(seed),
                "flexion_deg": [float(x) for x in flexions],
            },
        },
    )
    project_path = directory / PROJECT_NAME
    save_project(project, project_path)
    return project_path


def demo_project_path(cache_dir, frames: int = 4, image_size: int = 1024, seed: int = 0) -> Path:
    """The demo project in ``cache_dir/demo``, built only when missing or out of date."""
    cache_dir = Path(cache_dir).absolute()
    target = cache_dir / "demo"
    recipe = {"recipe_version": RECIPE_VERSION, "frames": int(frames), "image_size": int(image_size), "seed": int(seed)}
    if _cache_is_valid(target, recipe):
        return target / PROJECT_NAME
    try:
        cache_dir.mkdir(parents=True, exist_ok=True)
        scratch = Path(tempfile.mkdtemp(prefix=".demo-build-", dir=cache_dir))
    except OSError as exc:
        raise InputError(cache_dir, f"cannot create the demo cache: {describe_os_error(exc)}") from None
    try:
        build_demo_project(scratch, frames=frames, image_size=image_size, seed=seed)
        atomic_write_text(scratch / STAMP_NAME, json.dumps(recipe) + "\n")
        if target.exists():
            shutil.rmtree(target)
        os.replace(scratch, target)  # project paths are relative, so the move keeps them valid
    except OSError as exc:
        if _cache_is_valid(target, recipe):  # another process finished the same build first
            return target / PROJECT_NAME
        raise InputError(target, f"cannot write the demo cache: {describe_os_error(exc)}") from None
    finally:
        if scratch.exists():
            shutil.rmtree(scratch, ignore_errors=True)
    return target / PROJECT_NAME


def demo_views(image_size: int = 1024) -> list[View]:
    """The two demo views (looking at the world origin, +z towards the top of the image)."""
    scale = image_size / 1024.0
    views = []
    for k, (azimuth, elevation) in enumerate(zip(VIEW_AZIMUTHS_DEG, VIEW_ELEVATIONS_DEG)):
        a, e = np.radians(azimuth), np.radians(elevation)
        direction = np.array([np.cos(a) * np.cos(e), np.sin(a) * np.cos(e), np.sin(e)])
        # the field of view stays the same at any image size: the pitch scales instead
        view = View.looking_at(-SOURCE_TO_ISOCENTRE_MM * direction, [0, 0, 0], [0, 0, 1], SOURCE_TO_IMAGE_MM,
                               (image_size, image_size), PITCH_MM / scale, name=CAMERA_FOLDERS[k])
        cx, cy = view.principal_point
        du, dv = PRINCIPAL_OFFSETS_PX[k]
        views.append(dataclasses.replace(view, principal_point=(cx + du * scale, cy + dv * scale)))
    return views


def knee_bend_poses(flexion_deg: float, progress: float = 0.0) -> dict[str, np.ndarray]:
    """True poses {component: (x, y, z, alpha, beta, gamma)} at one instant of the bend.

    The tibia tilts forward with the flexion and sinks a little; the femur flexes about its
    condylar arc centre (its origin) with rollback, slight external rotation and varus.
    """
    shank = 0.3 * flexion_deg
    tibia = np.eye(4)
    tibia[:3, :3] = _rot_x(-shank) @ _rot_z(2.0 + 1.5 * progress)
    tibia[:3, 3] = [0.8, -3.0 + 4.0 * progress, -17.0 - 3.0 * progress]
    relative = np.eye(4)
    relative[:3, :3] = _rot_z(-0.12 * flexion_deg) @ _rot_y(1.5) @ _rot_x(flexion_deg)
    relative[:3, 3] = [0.6, 1.5 - 0.09 * flexion_deg, INSERT_MM]
    femur = tibia @ relative
    return {"femoral": matrix_to_pose(femur), "tibial": matrix_to_pose(tibia)}


def write_stl(path, vertices, faces) -> None:
    """A binary STL of a triangle mesh (float32 coordinates, as the format stores them)."""
    path = Path(path)
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
    record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
    data = np.zeros(len(faces), dtype=record)
    data["normal"] = normals
    data["corners"] = tri
    header = b"fluorogui demo phantom (mm)".ljust(80, b" ")
    try:
        with open(path, "wb") as handle:
            handle.write(header)
            handle.write(np.uint32(len(faces)).tobytes())
            handle.write(data.tobytes())
    except OSError as exc:
        raise InputError(path, f"could not save: {describe_os_error(exc)}") from None


# -- helpers --------------------------------------------------------------------------------
def _cache_is_valid(target: Path, recipe: dict) -> bool:
    try:
        stamp = json.loads((target / STAMP_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    if stamp != recipe:
        return False
    try:
        project = load_project(target / PROJECT_NAME)
    except InputError:
        return False
    files = [p for s in project.sequences for p in s.paths] + [m.mesh_path for m in project.models]
    return all(p.is_file() for p in files)


def _write_pairs_csv(path: Path, frames, sequences, base: Path) -> None:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["frame", *CAMERA_FOLDERS])
    for i, frame in enumerate(frames):
        writer.writerow([frame, *(s.paths[i].relative_to(base).as_posix() for s in sequences)])
    atomic_write_text(path, out.getvalue())


def _frustum(z0: float, z1: float, r0: float, r1: float, centre=(0.0, 0.0), n: int = 40):
    """Closed truncated cone along z (component frame): a bone shaft or a limb segment."""
    theta = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    ring = np.column_stack([np.cos(theta), np.sin(theta)])
    bottom = np.column_stack([centre + r0 * ring, np.full(n, z0)])
    top = np.column_stack([centre + r1 * ring, np.full(n, z1)])
    vertices = np.vstack([bottom, top, [[*centre, z0], [*centre, z1]]])
    i = np.arange(n)
    j = (i + 1) % n
    faces = np.vstack([
        np.column_stack([i, j, n + j]), np.column_stack([i, n + j, n + i]),
        np.column_stack([np.full(n, 2 * n), j, i]), np.column_stack([np.full(n, 2 * n + 1), n + i, n + j]),
    ])
    return vertices, faces


def _anatomy_meshes() -> dict:
    """Bones and limb segments, each attached to a component frame: name -> (component, v, f)."""
    parts = {
        "femur_bone": ("femoral", *_frustum(8.0, 320.0, 30.0, 15.0, (0.0, -4.0))),
        "tibia_bone": ("tibial", *_frustum(-320.0, -3.0, 14.0, 33.0, (2.0, 0.0))),
        "thigh": ("femoral", *_frustum(-35.0, 320.0, 56.0, 68.0, (0.0, -6.0))),
        "shank": ("tibial", *_frustum(-320.0, 20.0, 40.0, 52.0, (0.0, -10.0))),
    }
    return parts


def _blurred_coverage(view: View, meshes, sigma_px: float) -> np.ndarray:
    """Coverage of soft structures, rendered at 1 sample per pixel and blurred."""
    coverage = coverage_of_meshes(view, meshes, supersample=1).astype(np.float32)
    return cv2.GaussianBlur(coverage, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT)


def _render_view(view: View, implants, anatomy: dict, rng: np.random.Generator) -> np.ndarray:
    """One demo image: transmissions multiply (tissue, bone, metal) over a shaded background."""
    width, height = view.image_size
    scale = width / 1024.0
    background = shaded_background((width, height), rng).astype(np.float32)
    metal = coverage_of_meshes(view, implants, SUPERSAMPLE).astype(np.float32)
    tissue = _blurred_coverage(view, [anatomy["thigh"], anatomy["shank"]], 9.0 * scale)
    bone = _blurred_coverage(view, [anatomy["femur_bone"], anatomy["tibia_bone"]], 2.5 * scale)
    image = background * (1 - TISSUE_CONTRAST * tissue) * (1 - BONE_CONTRAST * bone) * (1 - IMPLANT_CONTRAST * metal)
    image = cv2.GaussianBlur(image, (0, 0), 0.8 * scale, borderType=cv2.BORDER_REFLECT)  # focal spot, screen
    image = 0.06 + (image - 0.06) * _intensifier_field(width, height)
    image = image + rng.normal(0.0, NOISE_SD, size=image.shape).astype(np.float32)
    return np.clip(image, 0.0, 1.0)


@functools.lru_cache(maxsize=4)
def _intensifier_field(width: int, height: int) -> np.ndarray:
    """Circular field of the image intensifier: 1 inside, 0 outside, a soft rim."""
    v, u = np.ogrid[0:height, 0:width]
    radius = np.hypot(u - (width - 1) / 2.0, v - (height - 1) / 2.0) / (FIELD_RADIUS_FRACTION * width)
    field = np.clip((1.0 - radius) * 40.0, 0.0, 1.0).astype(np.float32)
    field.flags.writeable = False
    return field


def _rot_x(deg: float) -> np.ndarray:
    return rotation_matrix(deg, 0.0, 0.0)


def _rot_y(deg: float) -> np.ndarray:
    return rotation_matrix(0.0, deg, 0.0)


def _rot_z(deg: float) -> np.ndarray:
    return rotation_matrix(0.0, 0.0, deg)


__all__ = ["RECIPE_VERSION", "build_demo_project", "demo_project_path", "demo_views", "knee_bend_poses",
           "write_stl"]
