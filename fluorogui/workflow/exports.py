"""Results out of a session (poses and kinematics CSV, Autoscoper ``.tra``, JointTrack
``.jts``, figures; for the analysis that continues elsewhere C3D, OpenSim ``.mot`` and
``.trc``, XMALab rigid-body CSV) and poses from other tools in; also kinematics of bare
pose files.

Every export that has a header names in it the software version, the side, the units and
the conventions (``fluorogui.core.knee.kinematics.SIGN_CONVENTIONS``). Output paths are
checked before any work, and every file is written atomically.

The motion files rest on a time base: the project's frame rate (``frame_rate``; kept in
``project.settings["time"]``, see ``fluorogui.io.motion_files``), time = frame ÷ fps. The
files that need time (C3D, ``.trc``, ``.mot``) refuse, naming the file, when there is none.
Their markers: per component, the world position (mm) of its anatomical frame's origin and
of the points ``MARKER_AXIS_MM`` along its x, y and z axes (``<component>_origin``,
``_x``, ``_y``, ``_z``). A pose goes into them when it is matched or accepted; poses placed
by hand or flagged for review and not accepted are left out (invalid / NaN) unless
``include_unreviewed``; failed or missing poses always are.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fluorogui import __version__
from fluorogui.core.knee.kinematics import (
    KINEMATICS_COLUMNS,
    SIGN_CONVENTIONS,
    KneeKinematics,
    check_side,
    knee_kinematics,
)
from fluorogui.core.projection.pose import matrix_to_pose, pose_to_matrix
from fluorogui.core.records import PoseRecord
from fluorogui.core.status import Status
from fluorogui.io.errors import InputError
from fluorogui.io.files import check_output_file, check_output_folder
from fluorogui.io.motion_files import (
    frame_times,
    store_frame_rate,
    stored_frame_rate,
    write_c3d,
    write_mot,
    write_trc,
    write_xromm_csv,
)
from fluorogui.io.pose_files import (
    POSE_KEYS,
    jointtrack_to_world_pose,
    pose_to_jointtrack,
    read_jts,
    read_pose_csv,
    read_tra,
    write_csv,
    write_jts,
    write_tra,
)
from fluorogui.workflow.events import SessionEvent
from fluorogui.workflow.history import Command
from fluorogui.workflow.knee import KNEE_COMPONENTS, KneeRow, record_sd

POSE_CONVENTION = ("pose x, y, z (mm), alpha, beta, gamma (deg) of the model in the calibration (world) frame: "
                   "X = R m + t, R = Ry(beta) Rz(gamma) Rx(alpha); m00..m33 the same pose as a 4x4 "
                   "model -> world matrix, row by row")
SD_KEYS = tuple(f"sd_{k}" for k in POSE_KEYS)


def header_lines(session, what: str) -> list[str]:
    side = session.side
    lines = [f"fluorogui {__version__} {what}",
             f"project: {session.path.name if session.path else '(unsaved)'}",
             f"side: {side if side else 'right (not set in the project; assumed)'}",
             "units: mm and degrees",
             POSE_CONVENTION,
             f"kinematics: {SIGN_CONVENTIONS}",
             "status: matched = both components passed their checks; needs_review = a component "
             "failed a check or was placed by hand; missing = a component has no pose (values NaN)"]
    for component in KNEE_COMPONENTS:
        try:
            matrix = session.anatomical_frame(component)
            source = session.anatomical_frame_source(component)
            lines.append(f"{component} anatomical frame ({source}; anatomical -> model): "
                         f"{json.dumps(np.round(matrix, 9).tolist())}")
        except (InputError, KeyError, ValueError) as exc:
            lines.append(f"{component} anatomical frame: unavailable ({exc})")
    return lines


def pose_columns(views: int) -> list[str]:
    columns = ["frame", "status", "reason"]
    for c in KNEE_COMPONENTS:
        columns += [f"{c}_status", *(f"{c}_{k}" for k in POSE_KEYS),
                    *(f"{c}_m{r}{k}" for r in range(4) for k in range(4)),
                    f"{c}_objective_mm", *(f"{c}_view{v + 1}_mm" for v in range(views)),
                    *(f"{c}_{k}" for k in SD_KEYS)]
    return columns + list(KINEMATICS_COLUMNS) + [f"{c}_sd" for c in KINEMATICS_COLUMNS]


def pose_rows(session, rows: list[KneeRow]) -> list[list]:
    views = session.n_views
    out = []
    for row in rows:
        cells: list = [row.frame, row.status, row.reason]
        for c in KNEE_COMPONENTS:
            record = row.records.get(c)
            if record is None:
                cells += ["missing", *([float("nan")] * (6 + 16 + 1 + views + 6))]
                continue
            match = record.match
            per_view = list(match.per_view_mean_mm) if match is not None else []
            per_view = (per_view + [float("nan")] * views)[:views]
            cells += [record.status + (" (reviewed)" if record.reviewed else ""),
                      *(float(v) for v in record.pose), *(float(v) for v in pose_to_matrix(record.pose).reshape(16)),
                      float(match.objective_mm) if match is not None else float("nan"),
                      *(float(v) for v in per_view), *(float(v) for v in record_sd(record))]
        cells += [float(v) for v in row.values.values()] + [float(v) for v in row.sd]
        out.append(cells)
    return out


def export_poses_csv(session, path, rows: list[KneeRow] | None = None) -> Path:
    """``rows``: the session's ``knee_rows()`` when the caller already has them."""
    path = check_output_file(path)
    rows = session.knee_rows() if rows is None else rows
    write_csv(path, header_lines(session, "poses and kinematics, one row per frame"),
              pose_columns(session.n_views), pose_rows(session, rows))
    return path


def export_kinematics_csv(session, path, rows: list[KneeRow] | None = None) -> Path:
    path = check_output_file(path)
    rows = session.knee_rows() if rows is None else rows
    write_csv(path, header_lines(session, "knee kinematics, one row per frame"),
              ["frame", *KINEMATICS_COLUMNS, "status", "reason"],
              [[r.frame, *(float(v) for v in r.values.values()), r.status, r.reason] for r in rows])
    return path


def unreviewed_matches(session) -> list[tuple[int, str, str]]:
    """(frame, component, reason) of every knee pose the matcher flagged for review that
    nobody has accepted since. ``.tra`` and ``.jts`` carry no status, so their exports
    leave these out (NaN) unless asked to include them."""
    return [(frame, c, record.reason) for frame in session.frames for c in KNEE_COMPONENTS
            if (record := session.project.poses.get((frame, c))) is not None
            and record.status == Status.NEEDS_REVIEW and not record.reviewed]


def _exported(record: PoseRecord | None, include_unreviewed: bool) -> bool:
    """Whether a pose goes into a file without a status column (.tra, .jts)."""
    if record is None or record.status == Status.FAILED:
        return False
    return include_unreviewed or record.status != Status.NEEDS_REVIEW or record.reviewed


def _pose_matrices(session, components, keep) -> list[list[np.ndarray | None]]:
    """Per frame, per component the pose's 4×4 (model → world), or None where ``keep``
    (given the pose record, or None) leaves it out."""
    table = []
    for frame in session.frames:
        records = [session.project.poses.get((frame, c)) for c in components]
        table.append([pose_to_matrix(r.pose) if keep(r) else None for r in records])
    return table


def export_tra(session, path, include_unreviewed: bool = False) -> Path:
    """Autoscoper: one row per frame, femoral then tibial, 16 numbers each (row by row);
    NaN where a pose is missing, failed or flagged for review and not accepted (unless
    ``include_unreviewed``: see ``unreviewed_matches``)."""
    path = check_output_file(path)
    write_tra(path, _pose_matrices(session, KNEE_COMPONENTS, lambda r: _exported(r, include_unreviewed)))
    return path


def export_jts(session, folder, view: int, include_unreviewed: bool = False) -> list[Path]:
    """JointTrack: ``femoral.jts`` and ``tibial.jts`` in ``view``'s (0-based) camera frame;
    the poses that ``export_tra`` leaves out are left out here too."""
    if not 0 <= view < session.n_views:
        raise InputError(folder, f"view {view + 1} does not exist (the session has {session.n_views})")
    folder = check_output_folder(folder)
    camera = session.views[view]
    written = []
    for c in KNEE_COMPONENTS:
        if session.project.model(c) is None:
            continue
        rows = []
        for frame in session.frames:
            record = session.project.poses.get((frame, c))
            rows.append(pose_to_jointtrack(record.pose, camera) if _exported(record, include_unreviewed) else None)
        write_jts(folder / f"{c}.jts", rows)
        written.append(folder / f"{c}.jts")
    return written


def export_plot(session, path, against: str = "frame", rows: list[KneeRow] | None = None) -> Path:
    from fluorogui.workflow.knee_plot import save_kinematics_figure

    path = check_output_file(path)
    if path.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise InputError(path, "the figure must be .png, .svg or .pdf")
    save_kinematics_figure(session.knee_rows() if rows is None else rows, path, side=session.side or "right",
                           against=against, title=session.path.stem if session.path else "")
    return path


# -- the time base ------------------------------------------------------------------------------
def frame_rate(session) -> float | None:
    """The project's frame rate (frames per second), or None when nobody gave one."""
    return stored_frame_rate(session.project.settings)


def set_frame_rate(session, fps: float | None, source: str = "user") -> None:
    """Keep the frame rate in the project (an undoable edit; None removes it)."""
    before = session.project.settings.get("time")
    probe: dict = {}
    store_frame_rate(probe, fps, source)  # checks fps before anything changes
    after = probe.get("time")

    def put(_key, value) -> None:
        if value is None:
            session.project.settings.pop("time", None)
        else:
            session.project.settings["time"] = dict(value)
        session._notify(SessionEvent.KNEE, "time")

    session.history.push(Command("Set frame rate" if fps is not None else "Remove frame rate", "time", before,
                                 after, put))


def require_frame_rate(session, path, fps: float | None = None) -> float:
    """``fps`` (an override for one export) or the project's frame rate; an InputError naming
    the file that needs it when there is neither."""
    rate = fps if fps is not None else frame_rate(session)
    if rate is None:
        raise InputError(path, "needs a frame rate (time = frame number / fps) and the project has none; "
                               "give the images' frame rate")
    return float(rate)


# -- motion files: markers, C3D, .trc, .mot, XMALab ----------------------------------------------
MARKER_AXIS_MM = 10.0
MARKER_POINTS = ("origin", "x", "y", "z")
MOT_COLUMNS = ("knee_flexion", "knee_varus", "knee_internal_rotation", "knee_medial_translation",
               "knee_anterior_translation", "knee_distraction")
MOT_METRES = (False, False, False, True, True, True)  # .mot holds translations in metres (OpenSim)


def in_motion_files(record: PoseRecord | None, include_unreviewed: bool) -> bool:
    """Whether a pose is valid in the motion files: matched or accepted; also placed or
    flagged (not accepted) ones when ``include_unreviewed``; never failed or missing ones."""
    if record is None or record.status == Status.FAILED:
        return False
    return record.is_matched or include_unreviewed


def left_out_of_motion_files(session) -> list[tuple[int, str, str]]:
    """(frame, component, why) of the poses that motion files leave out unless
    ``include_unreviewed``: placed by hand or flagged for review, and not accepted."""
    out = []
    for frame in session.frames:
        for c in KNEE_COMPONENTS:
            record = session.project.poses.get((frame, c))
            if record is not None and record.status != Status.FAILED and not record.is_matched:
                out.append((frame, c, record.reason or str(record.status)))
    return out


def motion_components(session) -> list[str]:
    return [c for c in KNEE_COMPONENTS if session.project.model(c) is not None]


def marker_labels(components) -> list[str]:
    return [f"{c}_{point}" for c in components for point in MARKER_POINTS]


def anatomical_markers(pose, anatomical_frame) -> np.ndarray:
    """World positions (4 × 3, mm) of the anatomical origin and of the points
    ``MARKER_AXIS_MM`` along its x, y and z axes, for a model pose and its anatomical frame
    (anatomical → model)."""
    placed = pose_to_matrix(pose) @ np.asarray(anatomical_frame, dtype=float)
    origin = placed[:3, 3]
    return np.vstack([origin, *(origin + MARKER_AXIS_MM * placed[:3, k] for k in range(3))])


def marker_table(session, include_unreviewed: bool = False) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Labels, points (frames × markers × 3, mm; NaN where left out) and validity
    (frames × markers) of every frame."""
    components = motion_components(session)
    frames_of = {c: session.anatomical_frame(c) for c in components}
    labels = marker_labels(components)
    points = np.full((len(session.frames), len(labels), 3), np.nan)
    for i, frame in enumerate(session.frames):
        for k, c in enumerate(components):
            record = session.project.poses.get((frame, c))
            if in_motion_files(record, include_unreviewed):
                points[i, 4 * k:4 * k + 4] = anatomical_markers(record.pose, frames_of[c])
    return labels, points, np.all(np.isfinite(points), axis=2)


def _descriptions(labels: list[str]) -> list[str]:
    words = {"origin": "anatomical origin", "x": f"{MARKER_AXIS_MM:g} mm along the anatomical x axis (right)",
             "y": f"{MARKER_AXIS_MM:g} mm along the anatomical y axis (anterior)",
             "z": f"{MARKER_AXIS_MM:g} mm along the anatomical z axis (proximal)"}
    return [f"{label.split('_')[0]} component: {words[label.split('_', 1)[1]]}, world mm" for label in labels]


def consecutive_frames(session) -> bool:
    """Whether the frame numbers follow one another: a C3D reader times its frames 1/fps
    apart, which is frame ÷ fps only then (the C3D keeps the true ones in FLUOROGUI:FRAMES)."""
    frames = session.frames
    return all(b - a == 1 for a, b in zip(frames, frames[1:]))


def export_c3d(session, path, fps: float | None = None, include_unreviewed: bool = False) -> Path:
    """C3D: the anatomical markers, POINT:RATE the frame rate, one C3D frame per project
    frame; poses left out (see the module) are invalid markers (residual −1)."""
    path = check_output_file(path)
    rate = require_frame_rate(session, path, fps)
    labels, points, valid = marker_table(session, include_unreviewed)
    write_c3d(path, labels, points, valid, rate, session.frames, _descriptions(labels))
    return path


def export_trc(session, path, fps: float | None = None, include_unreviewed: bool = False) -> Path:
    """OpenSim marker file: the C3D's markers, Frame# the project's frame number, Time = frame / fps."""
    path = check_output_file(path)
    rate = require_frame_rate(session, path, fps)
    labels, points, valid = marker_table(session, include_unreviewed)
    write_trc(path, labels, session.frames, frame_times(session.frames, rate), points, valid, rate)
    return path


def mot_table(rows: list[KneeRow], include_unreviewed: bool = False) -> np.ndarray:
    """The six Grood–Suntay values per row as ``.mot`` holds them (degrees; translations in
    metres); NaN where a component is missing, or its pose is left out (see the module)."""
    table = np.full((len(rows), 6), np.nan)
    for i, row in enumerate(rows):
        if row.status == Status.MATCHED or (include_unreviewed and row.status == "needs_review"):
            table[i] = row.values.values()
    table[:, 3:] /= 1000.0
    return table


def export_mot(session, path, rows: list[KneeRow] | None = None, fps: float | None = None,
               include_unreviewed: bool = False) -> Path:
    """OpenSim Storage: ``time`` and the six knee values named ``MOT_COLUMNS``."""
    path = check_output_file(path)
    rate = require_frame_rate(session, path, fps)
    rows = session.knee_rows() if rows is None else rows
    side = session.side or "right (assumed)"
    notes = [f"fluorogui {__version__} knee kinematics of {session.path.name if session.path else 'an unsaved project'}"
             f", {side} knee",
             "Units are S.I. units (second, meters): knee_medial_translation, knee_anterior_translation and "
             "knee_distraction in meters; knee_flexion, knee_varus and knee_internal_rotation in degrees",
             f"time is frame number / {rate:g} frames per second",
             f"{SIGN_CONVENTIONS}",
             "NaN where a component has no pose, or its pose was not matched or accepted"
             + (" (placed or flagged poses included)" if include_unreviewed else "")]
    write_mot(path, "knee_kinematics", list(MOT_COLUMNS), frame_times([r.frame for r in rows], rate),
              mot_table(rows, include_unreviewed), notes)
    return path


def export_xromm(session, path, include_unreviewed: bool = False) -> Path:
    """XMALab rigid-body transformations: per frame and component the pose's 4×4 (model →
    world, mm) column by column; NaN where the pose is left out (see the module)."""
    path = check_output_file(path)
    components = motion_components(session)
    matrices = _pose_matrices(session, components, lambda r: in_motion_files(r, include_unreviewed))
    write_xromm_csv(path, components, matrices)
    return path


# -- imports -----------------------------------------------------------------------------------
def read_poses_file(session, path, component: str | None = None, view: int = 0) -> dict[tuple[int, str], np.ndarray]:
    """Poses by (frame, component) from our CSV (long or wide), an Autoscoper ``.tra``
    (femoral then tibial; rows are the session's frames in order) or a JointTrack ``.jts``
    (``component`` says which; rows are the session's frames, in ``view``'s camera frame)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".jts":
        if component not in KNEE_COMPONENTS:
            raise InputError(path, "say which component a .jts file holds (femoral or tibial)")
        rows = read_jts(path)
        _check_row_count(path, len(rows), session.frames)
        camera = session.views[view]
        return {(f, component): jointtrack_to_world_pose(r, camera)
                for f, r in zip(session.frames, rows) if r is not None}
    if suffix == ".tra":
        components = ([c for c in KNEE_COMPONENTS if session.project.model(c) is not None]
                      if component is None else [component])
        rows = read_tra(path, len(components))
        _check_row_count(path, len(rows), session.frames)
        return {(f, c): matrix_to_pose(m) for f, row in zip(session.frames, rows)
                for c, m in zip(components, row) if m is not None}
    poses = read_pose_csv(path)
    unknown = sorted({f for f, _ in poses} - set(session.frames))
    if unknown:
        raise InputError(path, f"frame {unknown[0]} is not a frame of this session")
    return {k: v for k, v in poses.items() if np.all(np.isfinite(v)) and (component is None or k[1] == component)}


def _check_row_count(path: Path, rows: int, frames: list[int]) -> None:
    if rows != len(frames):
        raise InputError(path, f"has {rows} rows but the session has {len(frames)} frames")


def import_poses(session, path, component: str | None = None, view: int = 0, replace: bool = False,
                 kept: list | None = None) -> int:
    """Read poses from another tool into the session (status ``placed``, reason naming the
    file, so they are reviewed before use) as one undoable step; returns how many. Poses
    matched or accepted in the session are kept (their (frame, component) appended to
    ``kept``) unless ``replace``."""
    poses = read_poses_file(session, path, component, view)
    if not replace:
        for frame, c in sorted(poses):
            if c in session.matched_in(frame, c):
                del poses[(frame, c)]
                if kept is not None:
                    kept.append((frame, c))
    name = Path(path).name
    session.history.begin_macro(f"Import poses from {name}")
    try:
        for (frame, c), pose in sorted(poses.items()):
            session.set_record(c, frame, PoseRecord(pose, status=Status.PLACED, reason=f"imported from {name}"),
                               f"Import {c} pose")
    finally:
        session.history.end_macro()
    return len(poses)


# -- bare pose files (no session) -------------------------------------------------------------------
def kinematics_of_poses(poses: dict[tuple[int, str], np.ndarray], side: str, femoral_frame, tibial_frame
                        ) -> list[tuple[int, KneeKinematics, str]]:
    """Kinematics per frame of bare poses; NaN with a reason where a component is missing."""
    side = check_side(side)
    out = []
    for frame in sorted({f for f, _ in poses}):
        pose = {c: poses.get((frame, c)) for c in KNEE_COMPONENTS}
        lacking = [c for c in KNEE_COMPONENTS if pose[c] is None or not np.all(np.isfinite(pose[c]))]
        if lacking:
            reason = " and ".join(f"{c} pose {'missing' if pose[c] is None else 'is NaN'}" for c in lacking)
            out.append((frame, KneeKinematics.missing(), reason))
            continue
        values = knee_kinematics(pose_to_matrix(pose["femoral"]), pose_to_matrix(pose["tibial"]),
                                 femoral_frame, tibial_frame, side)
        out.append((frame, values, ""))
    return out
