"""Results out of a session, and poses from other tools in.

Each export format is declared once, in its own module of ``exports.formats`` that
registers an ``ExportFormat`` (``exports.registry``): its name (the command line's
``--name``), the dialog's label and file name, whether it needs a frame rate or the knee
rows, which poses it holds, and its writer. ``fluorogui export``'s options, the app's
export dialog and the docs' format table are made from the registry, so adding a format is
adding a module (see the developer page *Adding an export*). What the formats share is in
``tables`` (header lines, the poses-and-kinematics rows, which poses each kind of file
holds), ``timebase`` (the project's frame rate) and ``markers`` (the C3D / ``.trc``
anatomical markers); ``imports`` reads poses from other tools and bare pose files.

Every export that has a header names in it the software version, the side, the units and
the conventions (``fluorogui.core.knee.kinematics.SIGN_CONVENTIONS``). Output paths are
checked before any work, and every file is written atomically.

The names below are the package's public functions, importable from here as before.
"""
from fluorogui.workflow.exports.formats.c3d import export_c3d
from fluorogui.workflow.exports.formats.jts import export_jts
from fluorogui.workflow.exports.formats.kinematics_csv import export_kinematics_csv
from fluorogui.workflow.exports.formats.mot import MOT_COLUMNS, MOT_METRES, export_mot, mot_table
from fluorogui.workflow.exports.formats.plot import export_plot
from fluorogui.workflow.exports.formats.poses_csv import export_poses_csv
from fluorogui.workflow.exports.formats.tra import export_tra
from fluorogui.workflow.exports.formats.trc import export_trc
from fluorogui.workflow.exports.formats.xromm import export_xromm
from fluorogui.workflow.exports.imports import import_poses, kinematics_of_poses, read_poses_file
from fluorogui.workflow.exports.markers import (
    MARKER_AXIS_MM,
    MARKER_POINTS,
    anatomical_markers,
    marker_labels,
    marker_table,
)
from fluorogui.workflow.exports.registry import (
    ExportFormat,
    ExportOptions,
    export_notes,
    format_named,
    formats,
    register,
    write_exports,
)
from fluorogui.workflow.exports.tables import (
    POSE_CONVENTION,
    SD_KEYS,
    consecutive_frames,
    header_lines,
    in_motion_files,
    in_statusless_files,
    left_out_of_motion_files,
    motion_components,
    pose_columns,
    pose_rows,
    unreviewed_matches,
)
from fluorogui.workflow.exports.timebase import frame_rate, require_frame_rate, set_frame_rate

__all__ = [
    "MARKER_AXIS_MM", "MARKER_POINTS", "MOT_COLUMNS", "MOT_METRES", "POSE_CONVENTION", "SD_KEYS", "ExportFormat",
    "ExportOptions", "anatomical_markers", "consecutive_frames", "export_c3d", "export_jts", "export_kinematics_csv",
    "export_mot", "export_notes", "export_plot", "export_poses_csv", "export_tra", "export_trc", "export_xromm",
    "format_named", "formats", "frame_rate", "header_lines", "import_poses", "in_motion_files",
    "in_statusless_files", "kinematics_of_poses", "left_out_of_motion_files", "marker_labels", "marker_table",
    "mot_table", "motion_components", "pose_columns", "pose_rows", "read_poses_file", "register",
    "require_frame_rate", "set_frame_rate", "unreviewed_matches", "write_exports",
]
