"""Pose and kinematics files, out and in: our CSV, Autoscoper ``.tra``, JointTrack ``.jts``.

* **Our poses CSV (wide).** ``#`` comment lines (units, conventions, version, side), then
  one row per frame: for each component its pose (x, y, z, alpha, beta, gamma), its 4×4
  (row by row), status, objective and per-view residuals, SDs; then the kinematics.
* **Our poses CSV (long)**, what ``fluorogui kinematics --poses`` reads: columns
  ``frame,component,x,y,z,alpha,beta,gamma`` (the pose convention, docs/developer/conventions.rst).
* **Autoscoper ``.tra``.** One row per frame, per component 16 numbers (the 4×4 row by
  row; components in the order given), comma-separated, ``NaN`` where a frame has no pose.
* **JointTrack ``.jts``.** ``JT_EULER_312``, a column-title line, one row per frame of
  x, y, z, z-rot, x-rot, y-rot (mm, degrees) in a view's JointTrack camera frame (source at
  the origin looking down −Z, X along image columns, Y up the rows), ``NOT_OPTIMIZED``
  where missing.

Writers are atomic (nothing half-written is left); readers raise ``InputError`` naming
the file and line.
"""
from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np

from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.pose import angles_from_matrix, pose_to_matrix
from fluorogui.io.calibration import jointtrack_matrix
from fluorogui.io.errors import InputError, warn_input
from fluorogui.io.files import atomic_write_text, read_text_file

POSE_KEYS = ("x", "y", "z", "alpha", "beta", "gamma")
JTS_TITLE = "JT_EULER_312"
JTS_HEADER = ("          x_tran,          y_tran,          z_tran,"
              "                   z_rot,           x_rot,           y_rot")
NOT_OPTIMIZED = "NOT_OPTIMIZED"
MAX_ROWS = 1_000_000
MAX_POSE_VALUE = 1e7  # mm or degrees: anything larger is not a pose


def _number_text(value) -> str:
    value = float(value)
    return "NaN" if not math.isfinite(value) else repr(round(value, 10))


def read_text_lines(path: Path) -> list[str]:
    """The lines of a text file, opened the one checked way (regular file, size, not binary)."""
    return read_text_file(path, "pose file").splitlines()


def _float(path: Path, text: str, where: str) -> float:
    text = text.strip()
    if text.lower() in ("nan", ""):
        return float("nan")
    try:
        value = float(text)
    except ValueError:
        raise InputError(path, f"{where}: {text[:30]!r} is not a number") from None
    if math.isinf(value):
        raise InputError(path, f"{where}: infinite value")
    return value


# -- Autoscoper .tra -----------------------------------------------------------------------
def write_tra(path, matrices: list[list[np.ndarray | None]]) -> None:
    """One row per frame; ``matrices[i]`` holds each component's 4×4 (or None)."""
    lines = []
    for row in matrices:
        numbers = []
        for matrix in row:
            values = np.full(16, np.nan) if matrix is None else np.asarray(matrix, dtype=float).reshape(16)
            numbers.extend(_number_text(v) for v in values)
        lines.append(",".join(numbers))
    atomic_write_text(path, "\n".join(lines) + "\n")


def read_tra(path, components: int) -> list[list[np.ndarray | None]]:
    """Rows of ``components`` 4×4 matrices (None where the row holds NaN)."""
    path = Path(path)
    out = []
    for number, line in enumerate(read_text_lines(path), start=1):
        if not line.strip():
            continue
        fields = [f for f in line.replace("\t", ",").replace(" ", ",").split(",") if f.strip()]
        if len(fields) != 16 * components:
            raise InputError(path, f"line {number} has {len(fields)} numbers; expected {16 * components} "
                                   f"(16 per component, {components} component{'s' if components > 1 else ''})")
        values = np.array([_float(path, f, f"line {number}") for f in fields]).reshape(components, 4, 4)
        row = []
        for matrix in values:
            if np.isnan(matrix).any():
                row.append(None)
                continue
            _check_rigid(path, matrix, f"line {number}")
            row.append(matrix)
        out.append(row)
        if len(out) > MAX_ROWS:
            raise InputError(path, f"more than {MAX_ROWS} rows")
    if not out:
        raise InputError(path, "holds no poses")
    return out


def _check_rigid(path: Path, matrix: np.ndarray, where: str) -> None:
    R = matrix[:3, :3]
    if (not np.allclose(matrix[3], [0, 0, 0, 1], atol=1e-6) or np.abs(R.T @ R - np.eye(3)).max() > 1e-4
            or np.linalg.det(R) < 0):
        raise InputError(path, f"{where}: not a rigid transform (rotation and translation, last row 0 0 0 1)")


# -- JointTrack .jts ------------------------------------------------------------------------
def jointtrack_camera(view: View) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (rows: camera X, Y, Z in world coordinates) and origin of a view's
    JointTrack camera frame."""
    return np.vstack([view.e_u, -view.e_v, -view.normal]), np.asarray(view.source, dtype=float)


def pose_to_jointtrack(pose, view: View) -> np.ndarray:
    """Our pose (world frame) as a JointTrack row (x, y, z, z_rot, x_rot, y_rot) in ``view``."""
    M, source = jointtrack_camera(view)
    T = pose_to_matrix(pose)
    R = M @ T[:3, :3]
    t = M @ (T[:3, 3] - source)
    # R = Rz(z) Rx(x) Ry(y): R[2,1] = sin x, R[0,1] = -sin z cos x, R[2,0] = -cos x sin y
    x_rot = math.asin(max(-1.0, min(1.0, R[2, 1])))
    z_rot = math.atan2(-R[0, 1], R[1, 1])
    y_rot = math.atan2(-R[2, 0], R[2, 2])
    return np.array([*t, *np.degrees([z_rot, x_rot, y_rot])])


def jointtrack_to_world_pose(row, view: View) -> np.ndarray:
    """A JointTrack row in ``view``'s camera frame as our pose in the world frame."""
    row = np.asarray(row, dtype=float).reshape(6)
    M, source = jointtrack_camera(view)
    R = M.T @ jointtrack_matrix(row)
    t = M.T @ row[:3] + source
    return np.array([*t, *angles_from_matrix(R)])


def write_jts(path, rows: list[np.ndarray | None]) -> None:
    """A JointTrack pose file: JT_EULER_312, the column titles, one row per frame."""
    lines = [JTS_TITLE, JTS_HEADER]
    for row in rows:
        if row is None or not np.all(np.isfinite(row)):
            lines.append(NOT_OPTIMIZED)
            continue
        cells = [f"{float(v):16.7f}" for v in row]
        lines.append(",".join(cells[:3]) + ",        " + ",".join(cells[3:]))
    atomic_write_text(path, "\n".join(lines) + "\n")


def read_jts(path) -> list[np.ndarray | None]:
    """Rows (x, y, z, z_rot, x_rot, y_rot) of a JT_EULER_312 file, None where NOT_OPTIMIZED."""
    path = Path(path)
    lines = read_text_lines(path)
    content = [(n, line.strip()) for n, line in enumerate(lines, start=1) if line.strip()]
    if not content or content[0][1].upper() != JTS_TITLE:
        raise InputError(path, f"not a JointTrack pose file (the first line must be {JTS_TITLE})")
    if content[0][1] != JTS_TITLE:
        warn_input(path, f"the header {content[0][1][:20]!r} is not in capitals as JointTrack writes it; "
                         f"read as {JTS_TITLE}")
    out = []
    for number, line in content[1:]:
        fields = [f.strip() for f in line.replace("\t", ",").split(",") if f.strip()]
        if len(fields) == 1 and " " in fields[0]:
            fields = fields[0].split()
        if fields and fields[0].upper() == NOT_OPTIMIZED:
            out.append(None)
            continue
        if not out and fields and not _looks_numeric(fields[0]):
            continue  # the column-title line
        if len(fields) != 6:
            raise InputError(path, f"line {number} has {len(fields)} columns; expected 6 "
                                   "(x, y, z, z_rot, x_rot, y_rot) or NOT_OPTIMIZED")
        out.append(np.array([_float(path, f, f"line {number}") for f in fields]))
    if not out:
        raise InputError(path, "holds no poses")
    return out


def _looks_numeric(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return text.lower() == "nan"


# -- CSV -------------------------------------------------------------------------------------
def write_csv(path, header_comments: list[str], columns: list[str], rows: list[list]) -> None:
    """A CSV with ``#`` comment lines first; numbers NaN where missing."""
    buffer = io.StringIO()
    for comment in header_comments:
        buffer.write(f"# {' '.join(str(comment).split())}\n")
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_number_text(v) if isinstance(v, (float, np.floating)) else v for v in row])
    atomic_write_text(path, buffer.getvalue())


def read_csv_table(path, required: tuple[str, ...], lines: list[str] | None = None) -> list[dict]:
    """Rows (dicts) of a CSV whose ``#`` lines are comments; refuses missing columns and
    ragged rows. Each row's ``LINE`` key is its line number in the file, for messages."""
    path = Path(path)
    numbered = [(n, line) for n, line in enumerate(read_text_lines(path) if lines is None else lines, start=1)
                if not line.lstrip().startswith("#")]
    reader = csv.reader(line for _, line in numbered)

    def line_number() -> int:  # of the line the reader took last
        return numbered[reader.line_num - 1][0] if 0 < reader.line_num <= len(numbered) else reader.line_num

    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise InputError(path, "is empty") from None
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(path, f"line {line_number()}: the header lacks the column{'s' if len(missing) > 1 else ''} "
                               f"{', '.join(missing)} (expected {','.join(required)})")
    rows = []
    for fields in reader:
        if not any(f.strip() for f in fields):
            continue
        if len(fields) != len(header):
            raise InputError(path, f"line {line_number()} has {len(fields)} values; the header has {len(header)}")
        rows.append(dict(zip(header, (f.strip() for f in fields))) | {LINE: line_number()})
        if len(rows) > MAX_ROWS:
            raise InputError(path, f"more than {MAX_ROWS} rows")
    return rows


LINE = "\0line"  # the key of a row's line number (no column can be named so)


def read_long_poses(path, components=("femoral", "tibial"), lines: list[str] | None = None,
                    finite: bool = False) -> dict[tuple[int, str], np.ndarray]:
    """Poses by (frame, component) from a CSV with ``frame,component,x,y,z,alpha,beta,gamma``:
    the one reader of long pose tables (imported poses, the kinematics command, validation
    references). NaN poses are kept (as NaN) so the caller can report the frame, unless
    ``finite``; a repeated frame and component is refused."""
    path = Path(path)
    out: dict[tuple[int, str], np.ndarray] = {}
    for row in read_csv_table(path, ("frame", "component", *POSE_KEYS), lines):
        where = f"line {row[LINE]}"
        frame_text = row["frame"]
        try:
            frame = int(frame_text)
        except ValueError:
            raise InputError(path, f"{where}: frame {frame_text[:20]!r} is not a whole number") from None
        component = row["component"].lower()
        if component not in components:
            raise InputError(path, f"{where}: component {row['component'][:20]!r} "
                                   f"is not one of {', '.join(components)}")
        if (frame, component) in out:
            raise InputError(path, f"{where}: frame {frame} has a second {component} pose")
        pose = np.array([_float(path, row[k], f"{where}, {k}") for k in POSE_KEYS])
        if finite:
            for k, value in zip(POSE_KEYS, pose):
                if not np.isfinite(value):
                    raise InputError(path, f"{where}: column '{k}' is not a finite number: {row[k][:30]!r}")
                if abs(value) > MAX_POSE_VALUE:
                    raise InputError(path, f"{where}: column '{k}' is {row[k][:30]!r}; a pose value is at most "
                                           f"{MAX_POSE_VALUE:g} mm or degrees")
        out[(frame, component)] = pose
    if not out:
        raise InputError(path, "holds no poses")
    return out


def read_wide_poses(path, components=("femoral", "tibial"), lines: list[str] | None = None
                    ) -> dict[tuple[int, str], np.ndarray]:
    """Poses by (frame, component) from our wide export CSV (``femoral_x`` … columns)."""
    path = Path(path)
    rows = read_csv_table(path, ("frame",), lines)
    present = [c for c in components if rows and all(f"{c}_{k}" in rows[0] for k in POSE_KEYS)]
    if rows and not present:
        raise InputError(path, "has neither long (component, x, …) nor wide (femoral_x, …) pose columns")
    out = {}
    for row in rows:
        where = f"line {row[LINE]}"
        try:
            frame = int(row["frame"])
        except ValueError:
            raise InputError(path, f"{where}: frame {row['frame'][:20]!r} is not a whole number") from None
        for component in present:
            out[(frame, component)] = np.array(
                [_float(path, row[f"{component}_{k}"], f"{where}, {component}_{k}") for k in POSE_KEYS])
    if not out:
        raise InputError(path, "holds no poses")
    return out


def read_pose_csv(path, components=("femoral", "tibial")) -> dict[tuple[int, str], np.ndarray]:
    """Long or wide pose CSV, whichever the header says."""
    path = Path(path)
    lines = read_text_lines(path)  # read once, parsed by whichever reader the header asks for
    header = next((line for line in lines if line.strip() and not line.lstrip().startswith("#")), "")
    if "component" in [h.strip() for h in header.split(",")]:
        return read_long_poses(path, components, lines)
    return read_wide_poses(path, components, lines)


def read_reference_poses(path, component: str | None = None) -> list[tuple[int, str, np.ndarray]]:
    """(frame, component, pose) of every row of a long pose CSV (``read_long_poses``, finite
    values only), or of ``component``'s rows only, in frame order."""
    poses = read_long_poses(path, finite=True)
    return [(frame, name, pose) for (frame, name), pose in sorted(poses.items())
            if component is None or name == component]


def read_frame_json(path) -> "object":
    """A frame JSON ``{"matrix": [[4 rows of 4]]}`` (anatomical → model), checked."""
    from fluorogui.core.knee.kinematics import KinematicsError, check_frame
    from fluorogui.io.errors import InputError

    path = Path(path)
    text = "\n".join(read_text_lines(path))
    try:
        document = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise InputError(path, f"is not JSON ({getattr(exc, 'msg', 'too deeply nested')})") from None
    if not isinstance(document, dict) or "matrix" not in document:
        raise InputError(path, 'must be {"matrix": [[4 rows of 4 numbers]]}')
    try:
        return check_frame(document["matrix"])
    except KinematicsError as exc:
        raise InputError(path, f"'matrix': {exc}") from None
