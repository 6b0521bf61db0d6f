"""What the export formats share: the header lines, the poses-and-kinematics rows, which
poses each kind of file holds (files without a status column, motion files), the poses as
4×4 matrices, and whether the frame numbers are consecutive.

A file without a status column (``.tra``, ``.jts``) holds every pose but failed ones and,
unless asked, those flagged for review that nobody accepted. A motion file (C3D, ``.trc``,
``.mot``, XMALab) holds matched or accepted poses only, unless asked to hold placed and
flagged ones too; failed or missing poses never go in.
"""
from __future__ import annotations

import json

import numpy as np

from fluorogui import __version__
from fluorogui.core.knee.kinematics import KINEMATICS_COLUMNS, SIGN_CONVENTIONS
from fluorogui.core.projection.pose import pose_to_matrix
from fluorogui.core.records import PoseRecord
from fluorogui.core.status import Status
from fluorogui.io.errors import InputError
from fluorogui.io.pose_files import POSE_KEYS
from fluorogui.workflow.session.knee import KNEE_COMPONENTS, KneeRow, record_sd

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


# -- which poses a file holds ------------------------------------------------------------------
def unreviewed_matches(session) -> list[tuple[int, str, str]]:
    """(frame, component, reason) of every knee pose the matcher flagged for review that
    nobody has accepted since. ``.tra`` and ``.jts`` carry no status, so their exports
    leave these out (NaN) unless asked to include them."""
    return [(frame, c, record.reason) for frame in session.frames for c in KNEE_COMPONENTS
            if (record := session.project.poses.get((frame, c))) is not None
            and record.status == Status.NEEDS_REVIEW and not record.reviewed]


def in_statusless_files(record: PoseRecord | None, include_unreviewed: bool) -> bool:
    """Whether a pose goes into a file without a status column (.tra, .jts)."""
    if record is None or record.status == Status.FAILED:
        return False
    return include_unreviewed or record.status != Status.NEEDS_REVIEW or record.reviewed


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
    """The knee components the project has a model of (the motion files' bodies)."""
    return [c for c in KNEE_COMPONENTS if session.project.model(c) is not None]


def pose_matrices(session, components, keep) -> list[list[np.ndarray | None]]:
    """Per frame, per component the pose's 4×4 (model → world), or None where ``keep``
    (given the pose record, or None) leaves it out."""
    table = []
    for frame in session.frames:
        records = [session.project.poses.get((frame, c)) for c in components]
        table.append([pose_to_matrix(r.pose) if keep(r) else None for r in records])
    return table


def consecutive_frames(session) -> bool:
    """Whether the frame numbers follow one another: a C3D reader times its frames 1/fps
    apart, which is frame ÷ fps only then (the C3D keeps the true ones in FLUOROGUI:FRAMES)."""
    frames = session.frames
    return all(b - a == 1 for a, b in zip(frames, frames[1:]))
