"""Autoscoper ``.tra``: per frame the femoral then the tibial 4×4, row by row (``--tra``)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.io.files import check_output_file
from fluorogui.io.pose_files import write_tra
from fluorogui.workflow.exports.registry import ExportFormat, register
from fluorogui.workflow.exports.tables import in_statusless_files, pose_matrices
from fluorogui.workflow.session.knee import KNEE_COMPONENTS


def export_tra(session, path, include_unreviewed: bool = False) -> Path:
    """Autoscoper: one row per frame, femoral then tibial, 16 numbers each (row by row);
    NaN where a pose is missing, failed or flagged for review and not accepted (unless
    ``include_unreviewed``: see ``tables.unreviewed_matches``)."""
    path = check_output_file(path)
    write_tra(path, pose_matrices(session, KNEE_COMPONENTS, lambda r: in_statusless_files(r, include_unreviewed)))
    return path


FORMAT = register(ExportFormat(
    name="tra", order=30, label="Autoscoper poses (.tra)", default_name="{stem}.tra", metavar="OUT.tra",
    help="Autoscoper: femoral then tibial 4x4, row by row, per frame", short=".tra", statusless=True,
    write=lambda session, path, options: [export_tra(session, path, options.include_unreviewed)]))
