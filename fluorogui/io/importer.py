"""Build a Project from a user's files: calibrations, image sequences, implant models.

``import_session`` checks everything it can without reading whole sequences, so a bad
file is reported before any work starts: every calibration loads, the first image of
each view has the size its calibration expects (``check_image_size``) and is not blank
(refused when it is the view's only image, a warning in a sequence), every model
loads and has the size of a knee-implant component in millimetres, and the two views
have the same number of images (or a pairs CSV says which images go together). Every
problem is an ``InputError`` naming the file (or folder) at fault.

An image source is one of:

* a folder: its image files (TIFF, PNG, JPEG, BMP, DICOM), in natural name order
  ("frame_2" before "frame_10"), hidden files skipped;
* a list of image files, in the given order;
* one image file (a sequence of one frame);
* one multi-frame file (a DICOM run, a TIFF stack) or one video (AVI / MP4 / MOV / MKV):
  one frame reference ``FILE@N`` per frame, read lazily when the frame is shown or
  matched (``fluorogui.io.images.read_image``); nothing is extracted to disk
  (``extract_video_frames`` remains for users who want PNG files).

A pairs CSV (like ``data/biplane-tka/pairs.csv``) has a header ``frame,cam1,cam2`` and one
line per frame: the frame number, then one image path per view, relative to the CSV's
folder (absolute paths are kept). With it, the image sources are not needed.

``detect_biplane_folder`` recognises a folder laid out like ``data/biplane-tka``
(``calibration/``, ``cam1/``, ``cam2/``, ``models/``, ``pairs.csv``) and returns the
arguments of ``import_session`` for it; ``detect_single_plane_folder`` recognises one
calibrated view laid out like ``data/single-plane-tka`` (one calibration file, the images
beside it or in one image folder, the meshes beside it or in ``models/``). One view is a
valid session: out-of-plane translation (along the view's central ray) is then its weak
direction.

The frame rate (the project's time base, ``fluorogui.io.motion_files``) is read where the
images declare one: a video's container, a DICOM's FrameTime (ms per frame) or CineRate
(``source_frame_rate``). ``import_session`` keeps it when every view that declares one
agrees (``declared_frame_rates`` tells what each view said).
"""
from __future__ import annotations

import csv
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence, Union

import cv2
import numpy as np

from fluorogui.core.records import ImageSequence, ModelEntry, Project
from fluorogui.io.calibration import check_image_size, load_view
from fluorogui.io.errors import InputError, describe_os_error, warn_input
from fluorogui.io.files import read_text_file
from fluorogui.io.images import (
    DICOM_SUFFIXES,
    IMAGE_SUFFIXES,
    VIDEO_SUFFIXES,
    ImageInfo,
    check_not_blank,
    frame_count,
    frame_reference,
    has_dicom_preamble,
    image_info,
    read_image,
    split_frame_reference,
)
from fluorogui.io.meshes.read import MESH_SUFFIXES, load_mesh
from fluorogui.io.motion_files import MAX_FPS, store_frame_rate

ImageSource = Union[Path, str, Sequence[Union[Path, str]]]

#: Bounding-box diagonal (mm) a knee-implant component can plausibly have.
IMPLANT_DIAGONAL_MM = (20.0, 400.0)
CALIBRATION_SUFFIXES = (".txt", ".json", ".cfg", ".csv")
_CAMERA_FOLDER = re.compile(r"^(?:cam|camera|view)[ _-]?(\d+)$", re.IGNORECASE)
_CALIBRATION_FOLDERS = ("calibration", "calibrations", "calib")
_MODEL_FOLDERS = ("models", "model", "meshes")
_COMPONENT_HINTS = {"femoral": ("fem",), "tibial": ("tib",)}


# -- public API ---------------------------------------------------------------------------
def import_session(
    calibrations: Sequence[Path | str],
    image_sources: Sequence[ImageSource] | None,
    models: dict[str, Path | str],
    *,
    pairs_csv: Path | str | None = None,
    allow_unequal: bool = False,
) -> Project:
    """A new Project from calibration files, image sources (one per view) and models.

    ``models`` maps a component name ("femoral", "tibial") to its mesh file. With
    ``pairs_csv`` the frames and their images come from the CSV and ``image_sources`` is
    ignored (it may be empty). Views with different numbers of images are refused unless
    ``allow_unequal``: then the project has as many frames as the longest view, and the
    frames a shorter view lacks are flagged when they are matched. Raises InputError
    naming the offending file.
    """
    calibrations = [_absolute(p) for p in calibrations]
    if not calibrations:
        raise ValueError("at least one calibration is needed")
    views = [load_view(path) for path in calibrations]

    if pairs_csv is not None:
        frames, paths = read_pairs_csv(pairs_csv, len(views))
    else:
        sources = list(image_sources or [])
        if len(sources) != len(views):
            raise ValueError(f"{len(views)} calibrations need {len(views)} image sources, got {len(sources)}")
        paths = [resolve_image_source(source) for source in sources]
        counts = [len(p) for p in paths]
        if len(set(counts)) > 1 and not allow_unequal:
            k = next(i for i, n in enumerate(counts) if n != counts[0])
            raise InputError(
                _source_label(sources[k]),
                f"has {counts[k]} images but {_source_label(sources[0])} has {counts[0]}; both views need the "
                "same number of images (or give a pairs CSV saying which images go together)",
            )
        frames = list(range(max(counts)))

    for view, sequence in zip(views, paths):
        first = read_image(sequence[0])
        check_image_size(view, first.shape, sequence[0])
        _check_shows_something(first, sequence)

    entries = []
    for component, path in models.items():
        if not str(component).strip():
            raise ValueError("a model needs a component name")
        path = _absolute(path)
        check_implant_model(path)
        entries.append(ModelEntry(str(component), path))

    project = Project(
        views=views,
        sequences=[ImageSequence(p) for p in paths],
        frames=frames,
        models=entries,
    )
    rates = [r for r in declared_frame_rates(project) if r is not None]
    if rates and all(abs(fps - rates[0][0]) <= 1e-6 * rates[0][0] for fps, _ in rates):
        store_frame_rate(project.settings, rates[0][0], rates[0][1])
    return project


def source_frame_rate(path) -> tuple[float, str] | None:
    """(frames per second, where it was read) that an image file declares, or None: a
    video's container rate, a DICOM's FrameTime (ms per frame) or else its CineRate.
    ``path`` may be a frame reference ``FILE@N``; a file that cannot be read declares none."""
    path, _ = split_frame_reference(path)
    suffix = path.suffix.lower()
    try:
        if suffix in VIDEO_SUFFIXES:
            from fluorogui.io.video import video_info

            fps = video_info(path).fps
            return (fps, f"{path.name} (video)") if 0 < fps <= MAX_FPS else None
        if suffix in DICOM_SUFFIXES or (suffix not in IMAGE_SUFFIXES and has_dicom_preamble(path)):
            return _dicom_frame_rate(path)
    except (InputError, OSError):
        return None
    return None


def _dicom_frame_rate(path: Path) -> tuple[float, str] | None:
    from fluorogui.io.dicom import read_dicom_header

    dataset = read_dicom_header(path).dataset
    for keyword, to_fps in (("FrameTime", lambda ms: 1000.0 / ms if ms > 0 else 0.0),
                            ("CineRate", lambda rate: rate)):
        try:
            value = float(getattr(dataset, keyword, None) or 0.0)
        except (TypeError, ValueError):
            continue
        fps = to_fps(value) if np.isfinite(value) else 0.0
        if 0 < fps <= MAX_FPS:
            return fps, f"{path.name} (DICOM {keyword})"
    return None


def declared_frame_rates(project: Project) -> list[tuple[float, str] | None]:
    """Per view, the frame rate its first image declares (``source_frame_rate``) or None."""
    return [source_frame_rate(s.paths[0]) if s.paths else None for s in project.sequences]


def import_folder(folder, allow_unequal: bool = False) -> Project:
    """A new Project from a folder laid out like ``data/biplane-tka`` (see
    ``detect_biplane_folder``) or, with one calibrated view, like ``data/single-plane-tka``
    (``detect_single_plane_folder``); raises InputError naming the folder when it is neither."""
    found = detect_biplane_folder(folder) or detect_single_plane_folder(folder)
    if found is None:
        raise InputError(folder, "not a session folder: a biplane one needs calibration/ with one file per camera, "
                                 "cam1/ and cam2/ image folders and models/; a single-plane one needs one "
                                 "calibration file (e.g. JointTrack JT_INTCALIB) and its images")
    if not found["models"]:
        raise InputError(Path(folder) / "models", "no femoral or tibial mesh found (names must contain fem / tib)")
    return import_session(found["calibrations"], found["image_sources"], found["models"], pairs_csv=found["pairs_csv"],
                          allow_unequal=allow_unequal)


def check_implant_model(path) -> tuple[np.ndarray, np.ndarray]:
    """Load a mesh and check it has the size of a knee-implant component in mm."""
    vertices, faces = load_mesh(path)
    used = vertices[np.unique(faces)]
    diagonal = float(np.linalg.norm(used.max(axis=0) - used.min(axis=0)))
    low, high = IMPLANT_DIAGONAL_MM
    if not low <= diagonal <= high:
        raise InputError(
            path,
            f"implausible size for a knee-implant component: bounding-box diagonal {diagonal:.4g} "
            f"(expected {low:g} to {high:g} mm); is the mesh in mm?",
        )
    return vertices, faces


def _check_shows_something(first: np.ndarray, sequence: list[Path]) -> None:
    """A blank first image (``check_not_blank``) is refused when it is the view's only one;
    in a sequence it is a warning (a recording may begin before the beam), and tracking
    refuses each blank frame it is given, naming it."""
    try:
        check_not_blank(first, sequence[0])
    except InputError as exc:
        if len(sequence) == 1:
            raise
        warn_input(exc.path, f"{exc.problem}; its frame cannot be matched (the others are checked when they are)")


def resolve_image_source(source: ImageSource) -> list[Path]:
    """The frames of one view's source (folder, list of files, one image, one multi-frame file
    or one video); a frame of a multi-frame file or video is the reference ``FILE@N``."""
    if isinstance(source, (str, os.PathLike)):
        path = _absolute(source)
        if path.is_dir():
            return list_image_files(path)
        base, index = split_frame_reference(path)
        if not base.exists():
            raise InputError(base, "file or folder not found")
        if index is None and (path.suffix.lower() in VIDEO_SUFFIXES or frame_count(path) > 1):
            return [frame_reference(path, k) for k in range(frame_count(path))]
        return [_checked_image_file(path)]
    files = [_absolute(p) for p in source]
    if not files:
        raise ValueError("an empty list of image files")
    if len(files) == 1:
        return resolve_image_source(files[0])
    return [_checked_image_file(p) for p in files]


@dataclass
class SourcePreview:
    """What an image source holds, for an import dialog: frame count, the first frame's
    format / size / bit depth, and the first frame itself (2D float32 in [0, 1])."""

    frames: int
    info: ImageInfo
    first: np.ndarray

    def describe(self) -> str:
        info = self.info
        detail = f", {info.detail}" if info.detail and info.detail != "none" else ""
        return (f"{self.frames} frame{'s' if self.frames != 1 else ''}: {info.format} {info.width}x{info.height}, "
                f"{info.bits}-bit{detail}")


def preview_image_source(source: ImageSource) -> SourcePreview:
    """Frame count and first frame of one view's source; raises InputError naming the file."""
    frames = resolve_image_source(source)
    return SourcePreview(len(frames), image_info(frames[0]), read_image(frames[0]))


def list_image_files(folder) -> list[Path]:
    """Image files of a folder in natural name order; InputError when there are none."""
    folder = _absolute(folder)
    if not folder.is_dir():
        raise InputError(folder, "folder not found" if not folder.exists() else "is a file, not a folder")
    try:
        entries = list(folder.iterdir())
    except OSError as exc:
        raise InputError(folder, f"cannot list the folder: {describe_os_error(exc)}") from None
    files = [
        p for p in entries
        if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".") and p.is_file()
    ]
    if not files:
        raise InputError(folder, "contains no image files (TIFF, PNG, JPEG, BMP or DICOM)")
    return sorted(files, key=_natural_key)


def read_pairs_csv(path, n_views: int = 2) -> tuple[list[int], list[list[Path]]]:
    """Frames and, per view, the image of each frame, from a ``frame,cam1,cam2`` CSV."""
    path = _absolute(path)
    text = read_text_file(path, "CSV file")  # regular text files only
    rows = [(n, [c.strip() for c in row]) for n, row in enumerate(csv.reader(text.splitlines()), start=1)]
    rows = [(n, row) for n, row in rows if any(row)]
    if rows and rows[0][1][0].lower() == "frame":
        rows = rows[1:]
    if not rows:
        raise InputError(path, "lists no image pairs")
    frames: list[int] = []
    paths: list[list[Path]] = [[] for _ in range(n_views)]
    for n, row in rows:
        if len(row) != 1 + n_views:
            raise InputError(path, f"line {n} has {len(row)} columns, expected {1 + n_views} "
                                   "(frame, one image per view)")
        try:
            frame = int(row[0])
        except ValueError:
            raise InputError(path, f"line {n}: frame {row[0]!r} is not a whole number") from None
        if frame in frames:
            raise InputError(path, f"line {n} repeats frame {frame}")
        frames.append(frame)
        for k, cell in enumerate(row[1:]):
            image = Path(cell)
            image = image if image.is_absolute() else Path(os.path.normpath(path.parent / image))
            if not image.is_file():
                raise InputError(image, f"listed on line {n} of {path.name} but not found")
            try:
                paths[k].append(_checked_image_file(image))
            except InputError as exc:
                raise InputError(exc.path, f"{exc.problem} (listed on line {n} of {path.name})") from None
    return frames, paths


def extract_video_frames(
    video,
    out_dir=None,
    progress: Callable[[int], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> list[Path]:
    """Write a video's frames as 8-bit grayscale PNGs (once) and return their paths.

    ``out_dir`` defaults to ``<video stem>_frames`` beside the video. A previous
    extraction newer than the video is reused. ``progress(n)`` is called after each frame;
    ``cancel()`` returning True stops with an InputError.
    """
    video = _absolute(video)
    if not video.is_file():
        raise InputError(video, "file not found")
    out_dir = _absolute(out_dir) if out_dir is not None else video.with_name(video.stem + "_frames")
    done = out_dir / ".complete"
    if done.is_file() and done.stat().st_mtime >= video.stat().st_mtime:
        return list_image_files(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        for stale in list(out_dir.glob("frame_*.png")) + [done]:
            stale.unlink(missing_ok=True)  # a previous, outdated or interrupted extraction
    except OSError as exc:
        raise InputError(out_dir, f"cannot create the frame folder: {describe_os_error(exc)}") from None
    capture = cv2.VideoCapture(str(video))
    written: list[Path] = []
    try:
        if not capture.isOpened():
            raise InputError(video, "cannot open the video (corrupt file or unsupported codec)")
        while True:
            ok, frame = capture.read()
            if not ok:
                break
            if cancel is not None and cancel():
                raise InputError(video, "frame extraction cancelled")
            if frame.ndim == 3:
                frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)  # same luma weights as read_image
            if frame.dtype != np.uint8:
                frame = np.round(frame.astype(np.float64) / np.iinfo(frame.dtype).max * 255).astype(np.uint8)
            target = out_dir / f"frame_{len(written):06d}.png"
            if not cv2.imwrite(str(target), frame):
                raise InputError(target, "could not write the extracted frame")
            written.append(target)
            if progress is not None:
                progress(len(written))
    finally:
        capture.release()
    if not written:
        raise InputError(video, "the video has no readable frames")
    try:
        done.write_text(f"{len(written)}\n", encoding="utf-8")
    except OSError as exc:
        raise InputError(done, f"could not save: {describe_os_error(exc)}") from None
    return written


def detect_biplane_folder(folder) -> dict | None:
    """Arguments of ``import_session`` for a folder laid out like ``data/biplane-tka``, or None.

    Needed: a calibration folder (``calibration/``) with one calibration file per camera
    folder (``cam1/``, ``cam2/``; also ``camera1``, ``view1``...), matched by the camera
    name or number in the file name. Optional: ``models/`` with meshes whose names say
    "fem..." / "tib...", and ``pairs.csv``. Result keys: ``calibrations``,
    ``image_sources``, ``models``, ``pairs_csv`` (None when absent).
    """
    folder = _absolute(folder)
    children = _visible_children(folder)
    if children is None:
        return None
    cameras = sorted(
        ((int(m.group(1)), p) for p in children if p.is_dir() and (m := _CAMERA_FOLDER.match(p.name))),
        key=lambda item: item[0],
    )[:2]
    calibration_dir = _child_folder(children, _CALIBRATION_FOLDERS)
    if len(cameras) < 2 or calibration_dir is None:
        return None
    candidates = sorted(
        (p for p in calibration_dir.iterdir()
         if p.is_file() and p.suffix.lower() in CALIBRATION_SUFFIXES and not p.name.startswith(".")),
        key=_natural_key,
    )
    calibrations = []
    for number, camera in cameras:
        match = [p for p in candidates if camera.name.lower() in p.stem.lower()]
        if len(match) != 1:
            match = [p for p in candidates if re.search(rf"(?<!\d){number}(?!\d)", p.stem)]
        if len(match) != 1:
            if len(candidates) != len(cameras):
                return None
            match = [candidates[len(calibrations)]]
        calibrations.append(match[0])
    if len(set(calibrations)) != len(calibrations):
        return None

    models: dict[str, Path] = {}
    model_dir = _child_folder(children, _MODEL_FOLDERS)
    if model_dir is not None:
        meshes = [p for p in model_dir.iterdir() if p.is_file() and p.suffix.lower() in MESH_SUFFIXES]
        for component, hints in _COMPONENT_HINTS.items():
            found = sorted((p for p in meshes if any(h in p.stem.lower() for h in hints)), key=_natural_key)
            if found:
                models[component] = found[0]
    pairs = [p for p in children if p.is_file() and p.name.lower() == "pairs.csv"]
    return {
        "calibrations": calibrations,
        "image_sources": [camera for _, camera in cameras],
        "models": models,
        "pairs_csv": pairs[0] if pairs else None,
    }


def detect_single_plane_folder(folder) -> dict | None:
    """Arguments of ``import_session`` for one calibrated view, or None.

    Needed: exactly one calibration file that loads (in the folder or in ``calibration/``)
    and images: the folder's own image files, else its one image folder (or a video /
    multi-frame file). Meshes whose names say fem / tib, beside the images or in
    ``models/``. JointTrack pose files (``*.jts``) are left for the user to compare.
    """
    folder = _absolute(folder)
    children = _visible_children(folder)
    if children is None:
        return None
    calibration_dir = _child_folder(children, _CALIBRATION_FOLDERS)
    places = [folder] + ([calibration_dir] if calibration_dir is not None else [])
    calibrations = []
    for place in places:
        for p in sorted(place.iterdir(), key=_natural_key):
            if p.is_file() and p.suffix.lower() in CALIBRATION_SUFFIXES and not p.name.startswith(".") \
                    and p.name.lower() != "pairs.csv":
                try:
                    load_view(p)
                except InputError:
                    continue
                calibrations.append(p)
    if len(calibrations) != 1:
        return None
    images = [p for p in children if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES + VIDEO_SUFFIXES]
    image_dirs = [p for p in children if p.is_dir() and p != calibration_dir
                  and p.name.lower() not in _MODEL_FOLDERS and _has_images(p)]
    if images:
        source = images[0] if len(images) == 1 else folder
    elif len(image_dirs) == 1:
        source = image_dirs[0]
    else:
        return None
    models: dict[str, Path] = {}
    model_dir = _child_folder(children, _MODEL_FOLDERS)
    meshes = [p for p in (model_dir.iterdir() if model_dir is not None else children)
              if p.is_file() and p.suffix.lower() in MESH_SUFFIXES]
    for component, hints in _COMPONENT_HINTS.items():
        found = sorted((p for p in meshes if any(h in p.stem.lower() for h in hints)), key=_natural_key)
        if found:
            models[component] = found[0]
    return {"calibrations": calibrations, "image_sources": [source], "models": models, "pairs_csv": None}


def _has_images(folder: Path) -> bool:
    try:
        return any(p.suffix.lower() in IMAGE_SUFFIXES for p in folder.iterdir())
    except OSError:
        return False


# -- helpers --------------------------------------------------------------------------------
def _absolute(path) -> Path:
    return Path(os.path.normpath(Path(path).expanduser().absolute()))


def _natural_key(path: Path):
    return [(0, int(part), "") if part.isdigit() else (1, 0, part.lower()) for part in re.split(r"(\d+)", path.name)]


def _checked_image_file(path: Path) -> Path:
    base, index = split_frame_reference(path)
    if base.is_dir():
        raise InputError(base, "is a folder; give a folder as the whole image source, not in a list of files")
    if not base.exists():
        raise InputError(base, "file not found")
    suffix = base.suffix.lower()
    if suffix in VIDEO_SUFFIXES and index is None:
        raise InputError(base, "is a video: give it alone as the image source of its view, or one frame as FILE@N")
    if suffix not in IMAGE_SUFFIXES + VIDEO_SUFFIXES:
        raise InputError(base, f"unsupported image type '{suffix or '(none)'}' (use TIFF, PNG, JPEG, BMP or DICOM)")
    return path


def _source_label(source: ImageSource) -> Path:
    if isinstance(source, (str, os.PathLike)):
        return _absolute(source)
    files = [_absolute(p) for p in source]
    return files[0].parent if files else Path(".")


def _visible_children(folder: Path) -> list[Path] | None:
    """The folder's entries that are not hidden; None when it is no readable folder."""
    if not folder.is_dir():
        return None
    try:
        return [p for p in folder.iterdir() if not p.name.startswith(".")]
    except OSError:
        return None


def _child_folder(children: list[Path], names: Sequence[str]) -> Path | None:
    for name in names:
        for child in children:
            if child.is_dir() and child.name.lower() == name:
                return child
    return None


__all__ = [
    "check_implant_model",
    "declared_frame_rates",
    "detect_biplane_folder",
    "detect_single_plane_folder",
    "extract_video_frames",
    "import_session",
    "list_image_files",
    "preview_image_source",
    "read_pairs_csv",
    "resolve_image_source",
    "source_frame_rate",
]
