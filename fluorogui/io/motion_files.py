"""Motion files for the tools where the analysis continues, and the time base they need.

* **Time base.** A project's frame rate lives in ``project.settings["time"]`` as
  ``{"fps": 30.0, "source": "..."}`` (the source says where it came from: the user, a
  video's container, a DICOM's CineRate or FrameTime). Time = frame number ÷ fps.
* **C3D** (written with ``ezc3d``): 3-D markers in mm, ``POINT:RATE`` the frame rate, one
  C3D frame per given frame; a marker that is not valid in a frame has residual −1 (and
  zero coordinates, as the format says). The project's frame numbers and times are kept
  in the parameter group ``FLUOROGUI`` (``FRAMES``, ``TIMES``), since a C3D reader times
  its frames as evenly spaced.
* **OpenSim ``.mot``** (Storage): the header (name, ``version=1``, ``nRows``, ``nColumns``,
  ``inDegrees=yes``, free text lines, ``endheader``), then a tab-separated table whose first
  column is ``time``; ``NaN`` where a value is missing.
* **OpenSim ``.trc``**: the three header lines of a marker file (``PathFileType 4``, the
  rates, frame and marker counts, units), the marker names over their X/Y/Z columns, then
  ``Frame#``, ``Time`` and the coordinates; a missing marker's cells are empty (OpenSim
  reads them as NaN).
* **XMALab rigid-body transformations** (XROMM): a CSV with one row per frame and, per
  body, the 16 numbers of its 4×4 transform (model → world, mm) column by column, headed
  ``<body>_m11, <body>_m21, <body>_m31, <body>_m41, <body>_m12, …, <body>_m44``; ``NaN``
  where the body has no pose.

Every writer is atomic: the file is complete or the previous one is left as it was.
"""
from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np

from fluorogui.io.errors import InputError, describe_os_error
from fluorogui.io.files import atomic_write_text, write_target

TIME_KEY = "time"
MAX_FPS = 1e6  # frames per second; anything faster is not a fluoroscope


# -- the time base -------------------------------------------------------------------------------
def check_fps(value, where) -> float:
    """``value`` as a frame rate (a finite number above 0, at most ``MAX_FPS``) or an
    InputError naming ``where`` (a file or an option)."""
    try:
        fps = float(value)
    except (TypeError, ValueError):
        raise InputError(where, f"frame rate {str(value)[:30]!r} is not a number") from None
    if not math.isfinite(fps) or fps <= 0 or fps > MAX_FPS:
        raise InputError(where, f"frame rate {value!r} must be above 0 and at most {MAX_FPS:g} frames per second")
    return fps


def stored_frame_rate(settings: dict) -> float | None:
    """The frame rate kept in a project's settings, or None (absent or not a usable number)."""
    entry = settings.get(TIME_KEY) if isinstance(settings, dict) else None
    if not isinstance(entry, dict):
        return None
    try:
        return check_fps(entry.get("fps"), "settings")
    except InputError:
        return None


def frame_rate_source(settings: dict) -> str:
    """Where the stored frame rate came from ("" when there is none)."""
    if stored_frame_rate(settings) is None:
        return ""
    return str(settings[TIME_KEY].get("source", "") or "")


def store_frame_rate(settings: dict, fps: float | None, source: str = "user") -> None:
    """Keep ``fps`` (checked) in ``settings`` with where it came from; None removes it."""
    if fps is None:
        settings.pop(TIME_KEY, None)
        return
    settings[TIME_KEY] = {"fps": check_fps(fps, "frame rate"), "source": str(source)}


def frame_times(frames, fps: float) -> np.ndarray:
    """Seconds of each frame number: frame ÷ fps."""
    return np.asarray(list(frames), dtype=float) / float(fps)


# -- C3D -------------------------------------------------------------------------------------------------
def write_c3d(path, labels: list[str], points: np.ndarray, valid: np.ndarray, *, fps: float, frames,
              descriptions: list[str] | None = None) -> None:
    """Markers ``points`` (frames × markers × 3, mm) with ``valid`` (frames × markers)."""
    import ezc3d

    path = Path(path)
    points = np.asarray(points, dtype=float)
    valid = np.asarray(valid, dtype=bool) & np.all(np.isfinite(points), axis=2)
    n_frames, n_markers = points.shape[:2]
    if len(labels) != n_markers:
        raise ValueError(f"{len(labels)} labels for {n_markers} markers")
    data = np.zeros((4, n_markers, n_frames))
    data[:3] = np.where(valid[..., None], points, 0.0).transpose(2, 1, 0)
    data[3] = 1.0
    residuals = np.where(valid, 0.0, -1.0).T[None]  # valid: 0 (computed, not measured); invalid: -1
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = np.array([float(fps)])
    c3d["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c3d["data"]["points"] = data
    c3d["data"]["meta_points"] = {"residuals": residuals}
    c3d.add_parameter("POINT", "UNITS", ["mm"])
    if descriptions is not None:
        c3d.add_parameter("POINT", "DESCRIPTIONS", list(descriptions))
    frames = np.asarray(list(frames), dtype=float)
    c3d.add_parameter("FLUOROGUI", "FRAMES", frames, "the project's frame number of each C3D frame")
    c3d.add_parameter("FLUOROGUI", "TIMES", frames / float(fps), "seconds of each C3D frame: frame / fps")
    _atomic_binary(path, lambda temp: c3d.write(str(temp)), ".c3d")


def _atomic_binary(path: Path, write, suffix: str) -> None:
    """Let ``write(temp_path)`` write a file beside ``path``, then put it in place at once."""
    target = write_target(path)
    temp = None
    try:
        fd, temp = tempfile.mkstemp(prefix=f".{target.name}.{os.getpid()}.", suffix=suffix, dir=target.parent)
        os.close(fd)
        write(temp)
        with open(temp, "rb+") as handle:
            os.fsync(handle.fileno())
        try:
            mode = target.stat().st_mode & 0o777
        except FileNotFoundError:
            mode = 0o644
        os.chmod(temp, mode)
        os.replace(temp, target)
        temp = None
    except OSError as exc:
        raise InputError(path, f"could not save: {describe_os_error(exc)}") from None
    except RuntimeError as exc:  # ezc3d's own failures
        raise InputError(path, f"could not write the file: {exc}") from None
    finally:
        if temp is not None:
            try:
                os.unlink(temp)
            except OSError:
                pass


# -- OpenSim .mot ---------------------------------------------------------------------------------------
def _cell(value, empty: str = "NaN", digits: int = 10) -> str:
    value = float(value)
    return empty if not math.isfinite(value) else repr(round(value, digits))


def write_mot(path, name: str, columns: list[str], times: np.ndarray, *, table: np.ndarray, notes: list[str]) -> None:
    """An OpenSim Storage file: ``time`` then ``columns``; ``notes`` are free header lines
    (no ``=`` in them, so OpenSim does not take them for settings)."""
    table = np.asarray(table, dtype=float).reshape(len(times), len(columns))
    head = [name, "version=1", f"nRows={len(times)}", f"nColumns={len(columns) + 1}", "inDegrees=yes", ""]
    head += [" ".join(n.replace("=", " is ").split()) for n in notes]
    head += ["", "endheader", "\t".join(["time", *columns])]
    rows = ["\t".join([_cell(t, digits=9), *(_cell(v) for v in values)]) for t, values in zip(times, table)]
    atomic_write_text(path, "\n".join(head + rows) + "\n")


# -- OpenSim .trc -------------------------------------------------------------------------------------------
def write_trc(path, labels: list[str], frames, times: np.ndarray, *, points: np.ndarray, valid: np.ndarray,
              fps: float) -> None:
    """Markers (frames × markers × 3, mm); cells of a marker that is not valid are empty."""
    path = Path(path)
    points = np.asarray(points, dtype=float)
    valid = np.asarray(valid, dtype=bool) & np.all(np.isfinite(points), axis=2)
    frames = list(frames)
    n = len(labels)
    rate = f"{float(fps):.6g}"
    lines = ["\t".join(["PathFileType", "4", "(X/Y/Z)", path.name]),
             "\t".join(["DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units", "OrigDataRate",
                        "OrigDataStartFrame", "OrigNumFrames"]),
             "\t".join([rate, rate, str(len(frames)), str(n), "mm", rate, str(frames[0] if frames else 0),
                        str(len(frames))]),
             "\t".join(["Frame#", "Time", *(cell for label in labels for cell in (label, "", ""))]),
             "\t".join(["", "", *(f"{axis}{k + 1}" for k in range(n) for axis in "XYZ")]),
             ""]
    for frame, t, row, ok in zip(frames, times, points, valid):
        cells = [str(frame), _cell(t, digits=9)]
        for marker, good in zip(row, ok):
            cells += [_cell(v, empty="") if good else "" for v in marker]
        lines.append("\t".join(cells))
    atomic_write_text(path, "\n".join(lines) + "\n")


# -- XMALab rigid-body transformations --------------------------------------------------------------------
#: column names per body: m<row><column> of the 4×4, column by column (m14, m24, m34 the translation in mm)
XROMM_NAMES = tuple(f"m{row}{column}" for column in range(1, 5) for row in range(1, 5))


def write_xromm_csv(path, bodies: list[str], matrices: list[list[np.ndarray | None]]) -> None:
    """One row per frame; ``matrices[i][b]`` is body ``b``'s 4×4 in frame ``i`` (or None),
    written column by column (XMALab's order)."""
    lines = [",".join(f"{body}_{name}" for body in bodies for name in XROMM_NAMES)]
    for row in matrices:
        cells = []
        for matrix in row:
            values = np.full(16, np.nan) if matrix is None else np.asarray(matrix, dtype=float).reshape(4, 4).T.ravel()
            cells += [_cell(v) for v in values]
        lines.append(",".join(cells))
    atomic_write_text(path, "\n".join(lines) + "\n")


__all__ = ["MAX_FPS", "TIME_KEY", "XROMM_NAMES", "check_fps", "frame_rate_source", "frame_times",
           "store_frame_rate", "stored_frame_rate", "write_c3d", "write_mot", "write_trc", "write_xromm_csv"]
