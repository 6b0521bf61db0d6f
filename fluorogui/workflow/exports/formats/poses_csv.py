"""Poses, residuals, status, SDs and kinematics, one CSV row per frame (``--poses``)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.io.files import check_output_file
from fluorogui.io.pose_files import write_csv
from fluorogui.workflow.exports.registry import ExportFormat, register
from fluorogui.workflow.exports.tables import header_lines, pose_columns, pose_rows


def export_poses_csv(session, path, rows=None) -> Path:
    """``rows``: the session's ``knee_rows()`` when the caller already has them."""
    path = check_output_file(path)
    rows = session.knee_rows() if rows is None else rows
    write_csv(path, header_lines(session, "poses and kinematics, one row per frame"),
              pose_columns(session.n_views), pose_rows(session, rows))
    return path


FORMAT = register(ExportFormat(
    name="poses", order=10, label="Poses, residuals, status and kinematics (CSV)", default_name="{stem}_poses.csv",
    metavar="OUT.csv", help="both poses (6 numbers and the 4x4), residuals, status, SDs and kinematics, one row "
                            "per frame",
    short="poses CSV", kinematic=True, checked=True,
    write=lambda session, path, options: [export_poses_csv(session, path, options.rows)]))
