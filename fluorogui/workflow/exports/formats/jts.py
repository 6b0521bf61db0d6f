"""JointTrack ``femoral.jts`` and ``tibial.jts`` in one view's camera frame (``--jts DIR --view K``)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.io.errors import InputError
from fluorogui.io.files import check_output_folder
from fluorogui.io.pose_files import pose_to_jointtrack, write_jts
from fluorogui.workflow.exports.registry import ExportFormat, register
from fluorogui.workflow.exports.tables import in_statusless_files
from fluorogui.workflow.session.knee import KNEE_COMPONENTS


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
            rows.append(pose_to_jointtrack(record.pose, camera) if in_statusless_files(record, include_unreviewed)
                        else None)
        write_jts(folder / f"{c}.jts", rows)
        written.append(folder / f"{c}.jts")
    return written


FORMAT = register(ExportFormat(
    name="jts", order=40, label="JointTrack poses (femoral.jts, tibial.jts)", default_name="{stem}_jointtrack",
    metavar="DIR", help="JointTrack femoral.jts and tibial.jts (needs --view)", short=".jts", folder=True,
    needs_view=True, view_label="JointTrack camera", statusless=True,
    write=lambda session, path, options: export_jts(session, path, options.view, options.include_unreviewed)))
