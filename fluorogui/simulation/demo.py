"""The demo project: a complete, generated biplane session to try the app without data.

``build_demo_project(directory)`` writes, from nothing but code:

* ``models/femoral_component.stl`` and ``models/tibial_component.stl``: the procedural
  implant phantoms of ``fluorogui.simulation.phantoms`` (mm);
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

The pieces are shared with the generated benchmark sequences (``fluorogui.simulation.knee_bend``):
the view builder (``ViewSpec``, ``views_from_specs``), the anatomy (``anatomy_meshes``,
``posed_anatomy``), the image model (``render_view`` / ``xray_image``) and ``write_pairs_csv``.
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

from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.pose import matrix_to_pose, rotation_matrix, transform_points
from fluorogui.core.records import ImageSequence, ModelEntry, PoseRecord, Project
from fluorogui.io.calibration import save_view_json
from fluorogui.io.errors import InputError, describe_os_error
from fluorogui.io.files import atomic_write_text
from fluorogui.io.images import write_image
from fluorogui.io.project.document import load_project, save_project
from fluorogui.simulation.phantoms import femoral_component_mesh, tibial_component_mesh
from fluorogui.simulation.render import coverage_of_meshes, shaded_background

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
    anatomy = anatomy_meshes()
    sequences = [ImageSequence() for _ in views]
    for frame in frame_numbers:
        posed = [(transform_points(truth[frame][c], meshes[c][0]), meshes[c][1]) for c in COMPONENTS]
        soft = posed_anatomy(truth[frame], anatomy)
        for k, view in enumerate(views):
            image = render_view(view, [posed], soft, rng)
            path = directory / CAMERA_FOLDERS[k] / f"frame_{frame:03d}.png"
            write_image(path, image)
            sequences[k].paths.append(path)

    write_pairs_csv(directory / "pairs.csv", frame_numbers, sequences, directory)

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
    specs = [
        ViewSpec(CAMERA_FOLDERS[k], azimuth, elevation, SOURCE_TO_IMAGE_MM, SOURCE_TO_ISOCENTRE_MM, PITCH_MM,
                 PRINCIPAL_OFFSETS_PX[k])
        for k, (azimuth, elevation) in enumerate(zip(VIEW_AZIMUTHS_DEG, VIEW_ELEVATIONS_DEG))
    ]
    return views_from_specs(specs, image_size)


@dataclasses.dataclass(frozen=True)
class ViewSpec:
    """A virtual source-intensifier pair aimed at ``target`` (world mm).

    ``azimuth_deg`` is the beam direction (source towards intensifier) about +z, measured
    from +x; ``elevation_deg`` tilts the beam upwards (positive: source below the target);
    ``roll_deg`` turns the image axes about the beam (right-hand rule about the beam
    direction; 0: world +z points up the image). ``pitch_mm`` and ``principal_offset_px``
    are for a 1024-pixel image: other sizes keep the same field of view (the pitch scales,
    the offset scales with it).
    """

    name: str
    azimuth_deg: float
    elevation_deg: float
    source_to_image_mm: float
    source_to_target_mm: float
    pitch_mm: float
    principal_offset_px: tuple[float, float] = (0.0, 0.0)
    roll_deg: float = 0.0
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def beam_direction(self) -> np.ndarray:
        a, e = np.radians(self.azimuth_deg), np.radians(self.elevation_deg)
        return np.array([np.cos(a) * np.cos(e), np.sin(a) * np.cos(e), np.sin(e)])


def views_from_specs(specs, image_size: int = 1024) -> list[View]:
    """Views of ``image_size`` x ``image_size`` pixels built from ``ViewSpec`` s (+z up in the image)."""
    scale = image_size / 1024.0
    views = []
    for spec in specs:
        direction = spec.beam_direction()
        up = np.array([0.0, 0.0, 1.0])
        if spec.roll_deg:
            up = _rotated_about(up, direction, spec.roll_deg)
        target = np.asarray(spec.target, dtype=float)
        source = target - spec.source_to_target_mm * direction
        # the field of view stays the same at any image size: the pitch scales instead
        view = View.looking_at(source, target, up, spec.source_to_image_mm, image_size=(image_size, image_size),
                               pitch=spec.pitch_mm / scale, name=spec.name)
        cx, cy = view.principal_point
        du, dv = spec.principal_offset_px
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


def posed_anatomy(poses: dict, anatomy: dict) -> dict:
    """World-space anatomy meshes {name: (vertices, faces)} for component poses {component: pose}."""
    return {name: (transform_points(poses[c], v), f) for name, (c, v, f) in anatomy.items()}


def write_pairs_csv(path: Path, frames, sequences, base: Path) -> None:
    """``frame,cam1,cam2`` rows with image paths relative to ``base`` (what the importer reads)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["frame", *CAMERA_FOLDERS])
    for i, frame in enumerate(frames):
        writer.writerow([frame, *(s.paths[i].relative_to(base).as_posix() for s in sequences)])
    atomic_write_text(path, out.getvalue())


def _frustum(z0: float, z1: float, r0: float, r1: float, *, centre=(0.0, 0.0), n: int = 40):
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


def anatomy_meshes() -> dict:
    """Bones and limb segments, each attached to a component frame: name -> (component, v, f).

    Sized for components in the phantoms' frames (x ML, y AP, z proximal, tibial tray top
    at z = 0, femoral condyles below the femoral origin); ``posed_anatomy`` places them.
    """
    parts = {
        "femur_bone": ("femoral", *_frustum(8.0, 320.0, 30.0, 15.0, centre=(0.0, -4.0))),
        "tibia_bone": ("tibial", *_frustum(-320.0, -3.0, 14.0, 33.0, centre=(2.0, 0.0))),
        "thigh": ("femoral", *_frustum(-35.0, 320.0, 56.0, 68.0, centre=(0.0, -6.0))),
        "shank": ("tibial", *_frustum(-320.0, 20.0, 40.0, 52.0, centre=(0.0, -10.0))),
    }
    return parts


def _blurred_coverage(view: View, meshes, sigma_px: float) -> np.ndarray:
    """Coverage of soft structures, rendered at 1 sample per pixel and blurred."""
    coverage = coverage_of_meshes(view, meshes, supersample=1).astype(np.float32)
    return cv2.GaussianBlur(coverage, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT)


def render_view(view: View, metal_layers, anatomy: dict, rng: np.random.Generator) -> np.ndarray:
    """One X-ray-like image (H, W) float32 in [0, 1] of metal parts over anatomy.

    ``metal_layers`` is a list of layers, each a list of world-space meshes ``(vertices,
    faces)``; a layer's silhouette is the union of its meshes, rendered with ``SUPERSAMPLE``
    x ``SUPERSAMPLE`` samples per pixel. ``anatomy`` maps the names of ``anatomy_meshes``
    to world-space meshes. See ``xray_image``.
    """
    coverages = [coverage_of_meshes(view, layer, SUPERSAMPLE).astype(np.float32) for layer in metal_layers]
    return xray_image(view, coverages, anatomy, rng)


def xray_image(view: View, metal_coverages, anatomy: dict, rng: np.random.Generator, *,
               soft_downsample: int = 1) -> np.ndarray:
    """The image model: transmissions multiply over a shaded background, then blur, field, noise.

    Each metal coverage (H, W) in [0, 1] absorbs ``IMPLANT_CONTRAST`` of the X-rays, so
    where two layers overlap the image is darker, as behind two metal parts. Soft tissue
    and bone (``anatomy``, world-space meshes by ``anatomy_meshes`` name) are rendered at
    1 sample per pixel and blurred. Then the focal spot / screen blur, the circular
    intensifier field and Gaussian noise. Random draws come from ``rng`` in a fixed order
    (background, then noise). ``soft_downsample`` > 1 computes the smooth parts (the
    background and the blurred tissue and bone) on a grid that many times coarser and
    interpolates them up: nearly the same picture in less time (the demo uses 1).
    """
    width, height = view.image_size
    scale = width / 1024.0
    f = int(soft_downsample)
    if f < 1:
        raise ValueError("soft_downsample must be a positive integer")
    coarse = view if f == 1 else _coarser_view(view, f)
    size = coarse.image_size
    background = shaded_background(size, rng).astype(np.float32)
    tissue = _blurred_coverage(coarse, [anatomy["thigh"], anatomy["shank"]], 9.0 * scale / f)
    bone = _blurred_coverage(coarse, [anatomy["femur_bone"], anatomy["tibia_bone"]], 2.5 * scale / f)
    image = background * (1 - TISSUE_CONTRAST * tissue) * (1 - BONE_CONTRAST * bone)
    if f > 1:  # pixel centres: full-grid u = f u' + (f - 1) / 2, as cv2.resize maps them
        image = cv2.resize(image, (size[0] * f, size[1] * f), interpolation=cv2.INTER_LINEAR)[:height, :width]
    for metal in metal_coverages:
        image = image * (1 - IMPLANT_CONTRAST * np.asarray(metal, dtype=np.float32))
    image = cv2.GaussianBlur(image, (0, 0), 0.8 * scale, borderType=cv2.BORDER_REFLECT)  # focal spot, screen
    image = 0.06 + (image - 0.06) * intensifier_field(width, height)
    image = image + rng.normal(0.0, NOISE_SD, size=image.shape).astype(np.float32)
    return np.clip(image, 0.0, 1.0)


def _coarser_view(view: View, factor: int) -> View:
    """The same projection on a grid ``factor`` times coarser (covering the image, maybe a little more)."""
    width, height = view.image_size
    cx, cy = view.principal_point
    return dataclasses.replace(
        view,
        pitch=(view.pitch[0] * factor, view.pitch[1] * factor),
        principal_point=((cx - (factor - 1) / 2.0) / factor, (cy - (factor - 1) / 2.0) / factor),
        image_size=(-(-width // factor), -(-height // factor)),
    )


@functools.lru_cache(maxsize=4)
def intensifier_field(width: int, height: int) -> np.ndarray:
    """Circular field of the image intensifier: 1 inside, 0 outside, a soft rim."""
    v, u = np.ogrid[0:height, 0:width]
    radius = np.hypot(u - (width - 1) / 2.0, v - (height - 1) / 2.0) / (FIELD_RADIUS_FRACTION * width)
    field = np.clip((1.0 - radius) * 40.0, 0.0, 1.0).astype(np.float32)
    field.flags.writeable = False
    return field


def _rotated_about(vector, axis, deg: float) -> np.ndarray:
    """``vector`` turned by ``deg`` about the unit ``axis`` (right-hand rule, Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    v = np.asarray(vector, dtype=float)
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return v * c + np.cross(k, v) * s + k * (k @ v) * (1.0 - c)


def _rot_x(deg: float) -> np.ndarray:
    return rotation_matrix(deg, 0.0, 0.0)


def _rot_y(deg: float) -> np.ndarray:
    return rotation_matrix(0.0, deg, 0.0)


def _rot_z(deg: float) -> np.ndarray:
    return rotation_matrix(0.0, 0.0, deg)


__all__ = ["RECIPE_VERSION", "ViewSpec", "anatomy_meshes", "build_demo_project", "demo_project_path", "demo_views",
           "intensifier_field", "knee_bend_poses", "posed_anatomy", "render_view", "views_from_specs",
           "write_pairs_csv", "write_stl", "xray_image"]
