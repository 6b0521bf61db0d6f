"""Read and write the projection geometry of one fluoroscope view.

Formats, detected by content (never by extension):

* MayaCam 2.0 (XMALab export): sections ``image size``, ``camera matrix``, ``rotation``,
  ``translation``; OpenCV pinhole ``x_cam = R X + t``, pixel ``= K x_cam / z_cam``.
* MayaCam 1.0 (older XMALab / Maya export, read as Autoscoper's ``Camera::loadMayaCam1``):
  five lines of three numbers: camera position; rotations about the camera's x, y, z
  axes in degrees (camera-to-world ``Rz(line2[2]) Ry(line2[1]) Rx(line2[0])``, OpenGL
  camera looking down its -z with y up); film-plane offset (derived, ignored);
  ``u0, v0, Z`` (1-based MATLAB principal point with ``v0`` counted from the image
  bottom, focal length ``|Z|`` in pixels); ``scale, width, height`` (0 means 1024).
* JointTrack ``JT_INTCALIB``: principal distance, principal-point x / y offset, pixel
  pitch (mm). Camera frame: source at the origin looking down -Z, image y up.
* fluorogui JSON: ``{"format": "fluorogui-calibration", "version": 1, "view": {...}}``.
* A DICOM image whose header has the source distances and detector pixel spacing: a
  starting geometry (``fluorogui.io.dicom.dicom_starting_view``), to be refined.

Every view read is checked against what a fluoroscope can plausibly be (``io.plausible``:
image size, field of view, pixel pitch, source distance, principal point, source position),
so that an absurd number is refused here, naming the file and its field, and not later as
a mismatch with an image. Numbers must be plain decimals of the digits 0-9 (``1_000`` and
Arabic-Indic ``١٠٢٤``, which Python's ``float`` would read, are refused), a MayaCam 2.0
section may appear only once, and MayaCam 1.0's rotation angles must lie within ±360°. A
JointTrack header in lower case is read, with an ``InputWarning`` saying so.

Every format is written too (``save_view``), as exactly as it is read. MayaCam 2.0's
optional ``undistortion`` block (OpenCV's k1 k2 p1 p2 k3 ... with the file's K) is kept in
``view.extra["distortion"]`` and applied by ``fluorogui.core.calibration.distortion``.

JointTrack pose files (``JT_EULER_312``) are read here too since they live in the
JointTrack camera frame that ``JT_INTCALIB`` defines.
"""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from fluorogui.core.projection.geometry import DEFAULT_PITCH_MM, GeometryError, View
from fluorogui.core.projection.pose import angles_from_matrix
from fluorogui.io import plausible
from fluorogui.io.errors import InputError, warn_input
from fluorogui.io.files import atomic_write_text, check_input_file, read_input_bytes
from fluorogui.io.images import has_dicom_preamble
from fluorogui.io.schema import CalibrationDocument, DocumentError, describe, parse_json

CALIBRATION_FORMAT = "fluorogui-calibration"
CALIBRATION_VERSION = 1
JOINTTRACK_DEFAULT_IMAGE_SIZE = (1024, 1024)
MAYACAM2_SECTIONS = ("image size", "camera matrix", "rotation", "translation")
_SECTION_TITLE = re.compile(r"^[A-Za-z][A-Za-z _-]*$")
_NON_FINITE_WORDS = {"nan", "inf", "-inf", "infinity", "-infinity"}
_PLAIN_NUMBER = re.compile(r"^[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?$")  # ASCII digits only
#: MayaCam 1.0's rotation angles (degrees) beyond this are no turn a calibration writes
MAX_ANGLE_DEG = 360.0
# each format's name for the quantities ``plausible.view_problem`` judges
_MAYACAM2_FIELDS = {plausible.SIZE: "section 'image size'", plausible.FOCAL: "section 'camera matrix' (fx, fy)",
                    plausible.PITCH: "section 'camera matrix' (fx, fy)",
                    plausible.DISTANCE: "section 'camera matrix' (fx, fy)",
                    plausible.PRINCIPAL: "section 'camera matrix' (cx, cy)", plausible.SOURCE: "section 'translation'"}
_MAYACAM1_FIELDS = {plausible.SIZE: "line 5 (width, height)", plausible.FOCAL: "line 4 (focal length Z)",
                    plausible.PITCH: "line 4 (focal length Z)", plausible.DISTANCE: "line 4 (focal length Z)",
                    plausible.PRINCIPAL: "line 4 (u0, v0)", plausible.SOURCE: "line 1 (camera position)"}
_JOINTTRACK_FIELDS = {plausible.SIZE: "the image size", plausible.FOCAL: "JT_INTCALIB principal distance / pixel pitch",
                      plausible.PITCH: "JT_INTCALIB pixel pitch", plausible.DISTANCE: "JT_INTCALIB principal distance",
                      plausible.PRINCIPAL: "JT_INTCALIB principal point offsets", plausible.SOURCE: "JT_INTCALIB"}
_JSON_FIELDS = {plausible.SIZE: "view.image_size_px", plausible.FOCAL: "view.distance_mm / view.pitch_mm",
                plausible.PITCH: "view.pitch_mm", plausible.DISTANCE: "view.distance_mm",
                plausible.PRINCIPAL: "view.principal_point_px", plausible.SOURCE: "view.source_mm"}
_DICOM_FIELDS = {k: "DICOM header (source distances, pixel spacing)" for k in _JSON_FIELDS}


# -- public API ---------------------------------------------------------------------------
def load_view(path, name: str = "", *, image_size=JOINTTRACK_DEFAULT_IMAGE_SIZE) -> View:
    """Read a calibration file of any supported format into a View.

    ``name`` defaults to the file's stem. ``image_size`` (width, height) is only used by
    formats that do not store it (JointTrack).
    """
    path = check_input_file(path, "calibration file")  # before any open: a FIFO must not block
    if has_dicom_preamble(path):
        return _plausible(path, _dicom_view(path, name), _DICOM_FIELDS)
    text = _read_text(path)
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    if not lines:
        raise InputError(path, "calibration file is empty")
    try:
        if lines[0].startswith("{"):
            return _plausible(path, _parse_json(path, text, name), _JSON_FIELDS)
        name = name or path.stem
        if lines[0].upper() == "JT_INTCALIB":
            if lines[0] != "JT_INTCALIB":
                warn_input(path, f"the header {lines[0][:20]!r} is not in capitals as JointTrack writes it; "
                                 "read as JT_INTCALIB")
            return _plausible(path, _parse_jointtrack(path, lines, name, image_size), _JOINTTRACK_FIELDS)
        if lines[0].lower() in MAYACAM2_SECTIONS:
            return _plausible(path, _parse_mayacam2(path, lines, name), _MAYACAM2_FIELDS)
        if _looks_like_mayacam1(lines):
            return _plausible(path, _parse_mayacam1(path, lines, name), _MAYACAM1_FIELDS)
    except GeometryError as exc:
        raise InputError(path, f"invalid calibration: {exc}") from None
    raise InputError(
        path,
        "unknown calibration format (expected MayaCam 1.0 or 2.0, JointTrack JT_INTCALIB "
        "or a fluorogui calibration JSON)",
    )


def _plausible(path: Path, view: View, fields: dict) -> View:
    """``view`` if a fluoroscope can have it; else InputError naming the file and its field.
    The view remembers its file (``extra["file"]``) for later messages about it."""
    problem = plausible.view_problem(view)
    if problem:
        kind, sentence = problem
        raise InputError(path, f"{fields[kind]}: {sentence}")
    view.extra["file"] = str(path)
    return view


def save_view_json(view: View, path) -> None:
    """Write a view as fluorogui calibration JSON, atomically."""
    document = {"format": CALIBRATION_FORMAT, "version": CALIBRATION_VERSION, "view": view.to_dict()}
    atomic_write_text(path, json.dumps(document, indent=2, allow_nan=False) + "\n")


def save_view(view: View, path, fmt: str = "json") -> None:
    """Write a view in ``fmt``: "json", "mayacam2", "mayacam1" or "jointtrack", atomically.

    Numbers are written with 17 significant digits, so reading the file back gives the
    same numbers (round trip exact to ~1e-16 relative). Raises InputError naming the file
    when the format cannot hold the view (MayaCam 1.0: one focal length; JointTrack: a
    view in its own camera frame, square pixels).
    """
    writers = {"json": save_view_json, "mayacam2": save_view_mayacam2, "mayacam1": save_view_mayacam1,
               "jointtrack": save_view_jointtrack}
    if fmt not in writers:
        raise ValueError(f"unknown calibration format {fmt!r} (use {', '.join(writers)})")
    writers[fmt](view, path)


def _num(value: float) -> str:
    return repr(float(value))


def save_view_mayacam2(view: View, path) -> None:
    """Write a view as MayaCam 2.0 (XMALab's export: image size width first, K, R, t, and the
    ``undistortion`` block when the view carries OpenCV distortion coefficients)."""
    K, R, t = view.K, view.R, view.t
    lines = ["image size", f"{view.image_size[0]},{view.image_size[1]}", "", "camera matrix"]
    lines += [",".join(_num(v) for v in row) for row in K] + ["", "rotation"]
    lines += [",".join(_num(v) for v in row) for row in R] + ["", "translation"]
    lines += [_num(v) for v in t] + [""]
    distortion = view.extra.get("distortion") or {}
    if distortion.get("model") == "opencv":
        lines += ["undistortion", ",".join(_num(v) for v in distortion["coefficients"]), ""]
    atomic_write_text(path, "\n".join(lines))


def save_view_mayacam1(view: View, path) -> None:
    """Write a view as MayaCam 1.0 (the inverse of the reader: Autoscoper's Camera::loadMayaCam1)."""
    fx, fy = view.focal_px
    if abs(fx - fy) > 1e-9 * fx:
        raise InputError(path, f"MayaCam 1.0 holds one focal length; this view has {fx:.6g} and {fy:.6g} px")
    A = np.column_stack([view.e_u, -view.e_v, -view.normal])  # camera-to-world, OpenGL camera axes
    yaw = math.degrees(math.atan2(A[1, 0], A[0, 0]))
    pitch = math.degrees(math.atan2(-A[2, 0], math.hypot(A[2, 1], A[2, 2])))
    roll = math.degrees(math.atan2(A[2, 1], A[2, 2]))
    width, height = view.image_size
    u0 = view.principal_point[0] + 1.0  # 1-based, v0 counted from the image bottom
    v0 = (height - 1.0) - view.principal_point[1] + 1.0
    scale = 0.1
    rows = [
        view.source.tolist(),
        [roll, pitch, yaw],
        [scale * (width / 2 - u0), scale * (height / 2 - v0), -scale * fx],
        [u0, v0, -fx],
    ]
    text = "\n".join(",".join(_num(v) for v in row) for row in rows) + f"\n{scale},{width},{height}\n"
    atomic_write_text(path, text)


def save_view_jointtrack(view: View, path) -> None:
    """Write a view as JointTrack ``JT_INTCALIB``; only a view in JointTrack's own camera frame
    (source at the origin looking down -Z, image y up) with square pixels fits."""
    canonical = (np.allclose(view.source, 0, atol=1e-9) and np.allclose(view.normal, (0, 0, -1), atol=1e-12)
                 and np.allclose(view.e_u, (1, 0, 0), atol=1e-12) and np.allclose(view.e_v, (0, -1, 0), atol=1e-12))
    if not canonical:
        raise InputError(path, "JointTrack JT_INTCALIB holds a view in its own camera frame (source at the origin, "
                               "looking down -Z); this view is elsewhere: save it as MayaCam or JSON")
    if abs(view.pitch[0] - view.pitch[1]) > 1e-12 * view.pitch[0]:
        raise InputError(path, "JointTrack JT_INTCALIB needs square pixels")
    width, height = view.image_size
    pitch = view.pitch[0]
    x_off = (view.principal_point[0] - width / 2.0) * pitch
    y_off = (height / 2.0 - view.principal_point[1]) * pitch
    atomic_write_text(path, "JT_INTCALIB\n" + "\n".join(_num(v) for v in (view.distance, x_off, y_off, pitch)) + "\n")


def check_image_size(view: View, image_shape, path) -> None:
    """Raise InputError when an image of numpy shape ``image_shape`` does not fit ``view``."""
    height, width = int(image_shape[0]), int(image_shape[1])
    cal_w, cal_h = view.image_size
    if (width, height) != (cal_w, cal_h):
        label = f" '{view.name}'" if view.name else ""
        label += f" ({view.extra['file']})" if view.extra.get("file") else ""
        raise InputError(
            path, f"image is {width}x{height} px but the calibration{label} is for {cal_w}x{cal_h} px"
        )


def load_jointtrack_poses(path) -> np.ndarray:
    """Rows ``x, y, z, z_rot, x_rot, y_rot`` (mm, degrees) of a ``JT_EULER_312`` file, (N, 6)."""
    path = Path(path)
    lines = [line.strip() for line in _read_text(path).splitlines() if line.strip()]
    if not lines or lines[0].upper() != "JT_EULER_312":
        raise InputError(path, "not a JointTrack pose file (first line must be JT_EULER_312)")
    if lines[0] != "JT_EULER_312":
        warn_input(path, f"the header {lines[0][:20]!r} is not in capitals as JointTrack writes it; "
                         "read as JT_EULER_312")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        fields = _split_row(line)
        if not rows and not _is_number(fields[0]):
            continue  # the column-title line
        values = _numbers(path, fields, f"line {number}")
        if len(values) != 6:
            raise InputError(path, f"line {number} has {len(values)} numbers, expected 6")
        rows.append(values)
    if not rows:
        raise InputError(path, "JointTrack pose file has no poses")
    return np.array(rows, dtype=float)


def jointtrack_matrix(row) -> np.ndarray:
    """Rotation ``Rz Rx Ry`` of a JointTrack ``JT_EULER_312`` row (angles in degrees)."""
    _, _, _, z_rot, x_rot, y_rot = (float(v) for v in row)
    return _rot_z(z_rot) @ _rot_x(x_rot) @ _rot_y(y_rot)


def jointtrack_to_pose(row) -> np.ndarray:
    """A JointTrack row (x, y, z, z_rot, x_rot, y_rot) as our pose (x, y, z, alpha, beta, gamma).

    Same world frame (JointTrack's camera frame); only the angle convention changes.
    """
    row = np.asarray(row, dtype=float).reshape(6)
    alpha, beta, gamma = angles_from_matrix(jointtrack_matrix(row))
    return np.array([row[0], row[1], row[2], alpha, beta, gamma])


def _dicom_view(path: Path, name: str) -> View:
    """A starting view from a DICOM image's header (source distances, detector pixel spacing)."""
    from fluorogui.io.dicom import dicom_starting_view

    view = dicom_starting_view(path, name)
    if view is None:
        raise InputError(path, "DICOM header lacks DistanceSourceToDetector, DistanceSourceToPatient or "
                               "ImagerPixelSpacing, so it gives no view geometry; calibrate the view instead")
    return view


# -- reading helpers --------------------------------------------------------------------------
def _read_text(path: Path) -> str:
    raw = read_input_bytes(path, "calibration file", 10_000_000)  # regular files only, never blocks
    if b"\x00" in raw[:4096]:
        raise InputError(path, "binary file, not a text calibration")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _numbers(path: Path, fields, where: str) -> list[float]:
    values = []
    for field in fields:
        if field.lower().lstrip("+-") not in ("nan", "inf", "infinity") and not _PLAIN_NUMBER.match(field):
            raise InputError(path, f"non-numeric value {field[:30]!r} in {where} (a plain decimal number is expected)")
        try:
            value = float(field)
        except ValueError:
            raise InputError(path, f"non-numeric value {field[:30]!r} in {where}") from None
        if not math.isfinite(value):
            raise InputError(path, f"NaN or infinite value in {where}")
        values.append(value)
    return values


def _split_row(line: str) -> list[str]:
    fields = [f.strip() for f in line.split(",")]
    if len(fields) == 1:
        fields = line.split()
    return [f for f in fields if f]


# -- MayaCam 2.0 --------------------------------------------------------------------------
def _parse_mayacam2(path: Path, lines: list[str], name: str) -> View:
    sections: dict[str, list[list[str]]] = {}
    current = None
    for line in lines:
        if _SECTION_TITLE.match(line) and line.lower() not in _NON_FINITE_WORDS:
            current = line.lower()  # unknown sections are read and ignored
            if current in sections:
                raise InputError(path, f"the section '{current}' appears twice; a MayaCam 2.0 file has each once")
            sections[current] = []
        elif current is None:
            raise InputError(path, f"unexpected line {line!r} before the first MayaCam section")
        else:
            sections[current].append(_split_row(line))
    for section in MAYACAM2_SECTIONS:
        if section not in sections:
            raise InputError(path, f"MayaCam 2.0 file is missing the section '{section}'")

    def matrix(section: str, rows: int, cols: int) -> np.ndarray:
        values = [_numbers(path, row, f"section '{section}'") for row in sections[section]]
        if len(values) != rows or any(len(v) != cols for v in values):
            shape = f"{rows} rows of {cols} numbers" if rows > 1 else f"{cols} numbers"
            raise InputError(path, f"section '{section}' needs {shape}")
        return np.array(values, dtype=float)

    size = matrix("image size", 1, 2)[0]
    if np.any(size <= 0) or np.any(size != np.round(size)):
        raise InputError(path, "section 'image size' needs two positive whole numbers")
    K = matrix("camera matrix", 3, 3)
    R = matrix("rotation", 3, 3)
    rows = sections["translation"]
    t = matrix("translation", 1, 3)[0] if len(rows) == 1 else matrix("translation", 3, 1)[:, 0]
    if abs(np.linalg.det(K)) < 1e-9:
        raise InputError(path, "camera matrix is singular")
    view = View.from_pinhole(K, R, t, (int(size[0]), int(size[1])), pitch=DEFAULT_PITCH_MM, name=name)
    view.extra.update(source_format="MayaCam 2.0", pitch_assumed=True)
    if "undistortion" in sections:
        rows = [_numbers(path, row, "section 'undistortion'") for row in sections["undistortion"]]
        coefficients = [value for row in rows for value in row]
        if len(coefficients) not in (4, 5, 8, 12, 14):
            raise InputError(path, f"section 'undistortion' has {len(coefficients)} numbers; OpenCV's distortion "
                                   "model takes 4, 5, 8, 12 or 14 (k1 k2 p1 p2 [k3 [k4 k5 k6 ...]])")
        view.extra["distortion"] = {"model": "opencv", "camera_matrix": K.tolist(), "coefficients": coefficients}
    return view


# -- MayaCam 1.0 --------------------------------------------------------------------------
def _looks_like_mayacam1(lines: list[str]) -> bool:
    if len(lines) != 5:
        return False
    return all(len(_split_row(line)) == 3 for line in lines) and _is_number(_split_row(lines[0])[0])


def _parse_mayacam1(path: Path, lines: list[str], name: str) -> View:
    rows = [_numbers(path, _split_row(line), f"line {i + 1}") for i, line in enumerate(lines)]
    position = np.array(rows[0])
    roll, pitch, yaw = rows[1]  # rotations about the camera's x, y, z
    if max(abs(roll), abs(pitch), abs(yaw)) > MAX_ANGLE_DEG:
        angle = max(rows[1], key=abs)
        raise InputError(path, f"line 2 (rotation angles): {angle:.4g}° is beyond ±{MAX_ANGLE_DEG:g}°; "
                               "give the camera's rotations in degrees")
    u0_matlab, v0_matlab, z = rows[3]
    if any(s < 0 or s != int(s) for s in rows[4][1:]):
        raise InputError(path, "line 5 needs the image width and height as whole numbers")
    width = int(rows[4][1]) or 1024  # Autoscoper: 0 means 1024
    height = int(rows[4][2]) or 1024
    focal = abs(z)
    if focal < 1e-9:
        raise InputError(path, "camera matrix is singular (focal length Z on line 4 is zero)")
    # camera-to-world rotation of the OpenGL camera (x right, y up, looking down -z)
    A = _rot_z(yaw) @ _rot_y(pitch) @ _rot_x(roll)
    cx = u0_matlab - 1.0
    cy = (height - 1.0) - (v0_matlab - 1.0)  # bottom-up rows to top-down rows
    view = View(
        source=position,
        normal=-A[:, 2],
        e_u=A[:, 0],
        e_v=-A[:, 1],
        distance=focal * DEFAULT_PITCH_MM,
        pitch=(DEFAULT_PITCH_MM, DEFAULT_PITCH_MM),
        principal_point=(cx, cy),
        image_size=(width, height),
        name=name,
    )
    view.extra.update(source_format="MayaCam 1.0", pitch_assumed=True)
    return view


# -- JointTrack ----------------------------------------------------------------------------
def _parse_jointtrack(path: Path, lines: list[str], name: str, image_size) -> View:
    if len(lines) < 5:
        raise InputError(
            path, "JT_INTCALIB needs 4 numbers: principal distance, x offset, y offset, pixel pitch (mm)"
        )
    distance, x_off, y_off, pitch = _numbers(path, [line.split()[0] for line in lines[1:5]], "JT_INTCALIB")
    width, height = (int(s) for s in image_size)
    if pitch <= 0 or distance <= 0:
        raise InputError(path, "JT_INTCALIB principal distance and pixel pitch must be positive")
    if not plausible.PITCH_MM[0] <= pitch <= plausible.PITCH_MM[1]:  # before dividing by it
        raise InputError(path, f"JT_INTCALIB pixel pitch: pixel pitch {pitch:.4g} mm is not plausible for a "
                               f"fluoroscope ({plausible.PITCH_MM[0]:g} to {plausible.PITCH_MM[1]:g} mm)")
    view = View(
        source=(0.0, 0.0, 0.0),
        normal=(0.0, 0.0, -1.0),
        e_u=(1.0, 0.0, 0.0),
        e_v=(0.0, -1.0, 0.0),
        distance=distance,
        pitch=(pitch, pitch),
        principal_point=(width / 2.0 + x_off / pitch, height / 2.0 - y_off / pitch),
        image_size=(width, height),
        name=name,
    )
    view.extra.update(source_format="JointTrack JT_INTCALIB", image_size_assumed=True)
    return view


# -- our JSON -----------------------------------------------------------------------------------
def _parse_json(path: Path, text: str, name: str) -> View:
    try:
        document = parse_json(text)
    except DocumentError as exc:
        raise InputError(path, f"calibration file: {exc}") from None
    if not isinstance(document, dict) or document.get("format") != CALIBRATION_FORMAT:
        raise InputError(path, "JSON file is not a fluorogui calibration")
    version = document.get("version")
    if not isinstance(version, int):
        raise InputError(path, "calibration JSON has no integer 'version'")
    if version > CALIBRATION_VERSION:
        raise InputError(
            path,
            f"written by a newer fluorogui (calibration version {version} > {CALIBRATION_VERSION}); "
            "update fluorogui to open it",
        )
    if not isinstance(document.get("view"), dict):
        raise InputError(path, "calibration JSON is missing the field 'view'")
    try:
        CalibrationDocument.model_validate(document)
    except ValidationError as exc:
        raise InputError(path, describe(exc)) from None
    stored = document["view"]
    view = View.from_dict({**stored, "name": name or stored.get("name") or path.stem})
    view.extra.update(source_format="fluorogui JSON")
    return view


# -- rotations (degrees) ----------------------------------------------------------------------
def _rot_x(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _rot_y(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rot_z(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
