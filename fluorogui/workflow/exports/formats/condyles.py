"""The condyles' contact points as markers (``--condyles OUT.c3d|OUT.trc``): each femoral
condyle's lowest point on the tray (``workflow.contact``) in world mm, the same space as the
anatomical markers of ``--c3d`` / ``--trc``, timed as they are (time = frame / fps). A frame
whose femoral or tibial pose the motion files leave out (not matched or accepted, unless
``--include-unreviewed``) has invalid markers."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fluorogui.io.files import check_output_file
from fluorogui.io.motion_files import frame_times, write_c3d, write_trc
from fluorogui.workflow.exports.registry import ExportFormat, register
from fluorogui.workflow.exports.tables import consecutive_frames, in_motion_files
from fluorogui.workflow.exports.timebase import require_frame_rate

CONDYLE_MARKERS = ("medial_contact", "lateral_contact")
DESCRIPTIONS = ("medial femoral condyle's lowest point on the tibial tray (Banks), world mm",
                "lateral femoral condyle's lowest point on the tibial tray (Banks), world mm")


def condyle_marker_table(session, include_unreviewed: bool = False, knee_rows=None) -> tuple[np.ndarray, np.ndarray]:
    """Points (frames × 2 × 3, world mm; NaN where left out) and validity (frames × 2) of
    ``CONDYLE_MARKERS`` in every frame of the session."""
    from fluorogui.workflow.contact import contact_rows, contact_world_points

    rows = {r.frame: r for r in contact_rows(session, knee_rows=knee_rows)}
    tibial_frame = session.anatomical_frame("tibial")
    side = session.side or "right"
    points = np.full((len(session.frames), len(CONDYLE_MARKERS), 3), np.nan)
    for i, frame in enumerate(session.frames):
        row = rows.get(frame)
        records = [session.project.poses.get((frame, c)) for c in ("femoral", "tibial")]
        if row is None or row.status == "missing" or not all(in_motion_files(r, include_unreviewed) for r in records):
            continue
        world = contact_world_points(row, records[1].pose, tibial_frame, side)
        points[i] = [world[name.split("_")[0]] for name in CONDYLE_MARKERS]
    return points, np.all(np.isfinite(points), axis=2)


def export_condyle_markers(session, path, fps: float | None = None, include_unreviewed: bool = False,
                           knee_rows=None) -> Path:
    """C3D or ``.trc`` (by the suffix) of ``CONDYLE_MARKERS``, timed as ``--c3d`` / ``--trc``."""
    path = check_output_file(path)
    rate = require_frame_rate(session, path, fps)
    points, valid = condyle_marker_table(session, include_unreviewed, knee_rows)
    labels = list(CONDYLE_MARKERS)
    if path.suffix.lower() == ".c3d":
        write_c3d(path, labels, points, valid, fps=rate, frames=session.frames, descriptions=list(DESCRIPTIONS))
    else:
        write_trc(path, labels, session.frames, frame_times(session.frames, rate), points=points, valid=valid,
                  fps=rate)
    return path


def _caveat(session) -> str:
    if consecutive_frames(session):
        return ""
    return ("the project's frame numbers are not consecutive: as C3D, its frames are timed one 1/fps apart by a "
            "reader; FLUOROGUI:FRAMES and FLUOROGUI:TIMES hold the true ones (a .trc carries them)")


FORMAT = register(ExportFormat(
    name="condyles", order=75, label="Condyle contact points as markers (C3D or .trc)",
    default_name="{stem}_condyles.c3d", metavar="OUT.c3d|OUT.trc",
    help="markers medial_contact and lateral_contact: each condyle's lowest point on the tray, world mm, one "
         "frame per frame",
    short="condyle markers", timed=True, motion=True, kinematic=True, suffixes=(".c3d", ".trc"),
    suffix_problem="the file must be .c3d or .trc (the suffix chooses the format)", caveat=_caveat,
    write=lambda session, path, options: [export_condyle_markers(session, path, options.fps,
                                                                 options.include_unreviewed, options.rows)]))
