"""XMALab rigid-body transformations: per component the 4×4, column by column (``--xromm``)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.io.files import check_output_file
from fluorogui.io.motion_files import write_xromm_csv
from fluorogui.workflow.exports.registry import ExportFormat, register
from fluorogui.workflow.exports.tables import in_motion_files, motion_components, pose_matrices


def export_xromm(session, path, include_unreviewed: bool = False) -> Path:
    """XMALab rigid-body transformations: per frame and component the pose's 4×4 (model →
    world, mm) column by column; NaN where the pose is left out (see ``exports.tables``)."""
    path = check_output_file(path)
    components = motion_components(session)
    matrices = pose_matrices(session, components, lambda r: in_motion_files(r, include_unreviewed))
    write_xromm_csv(path, components, matrices)
    return path


FORMAT = register(ExportFormat(
    name="xromm", order=90, label="XMALab rigid-body transformations (CSV)", default_name="{stem}_xromm.csv",
    metavar="OUT.csv", help="XMALab rigid-body transformations: per component 16 numbers (the 4x4, column by "
                            "column) per frame",
    short="XMALab", motion=True,
    write=lambda session, path, options: [export_xromm(session, path, options.include_unreviewed)]))
