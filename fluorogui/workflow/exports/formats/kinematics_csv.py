"""The knee kinematics, one CSV row per frame with its status and reason (``--kinematics``)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.core.knee.kinematics import KINEMATICS_COLUMNS
from fluorogui.io.files import check_output_file
from fluorogui.io.pose_files import write_csv
from fluorogui.workflow.exports.registry import ExportFormat, register
from fluorogui.workflow.exports.tables import header_lines


def export_kinematics_csv(session, path, rows=None) -> Path:
    path = check_output_file(path)
    rows = session.knee_rows() if rows is None else rows
    write_csv(path, header_lines(session, "knee kinematics, one row per frame"),
              ["frame", *KINEMATICS_COLUMNS, "status", "reason"],
              [[r.frame, *(float(v) for v in r.values.values()), r.status, r.reason] for r in rows])
    return path


FORMAT = register(ExportFormat(
    name="kinematics", order=20, label="Kinematics (CSV)", default_name="{stem}_kinematics.csv",
    metavar="OUT.csv", help="knee kinematics, one row per frame", short="kinematics CSV", kinematic=True,
    checked=True, write=lambda session, path, options: [export_kinematics_csv(session, path, options.rows)]))
