"""C3D anatomical markers, POINT:RATE the frame rate, one C3D frame per project frame (``--c3d``)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.io.files import check_output_file
from fluorogui.io.motion_files import write_c3d
from fluorogui.workflow.exports.markers import marker_descriptions, marker_table
from fluorogui.workflow.exports.registry import ExportFormat, register
from fluorogui.workflow.exports.tables import consecutive_frames
from fluorogui.workflow.exports.timebase import require_frame_rate


def export_c3d(session, path, fps: float | None = None, include_unreviewed: bool = False) -> Path:
    """C3D: the anatomical markers, POINT:RATE the frame rate, one C3D frame per project
    frame; poses left out (see ``exports.tables``) are invalid markers (residual −1)."""
    path = check_output_file(path)
    rate = require_frame_rate(session, path, fps)
    labels, points, valid = marker_table(session, include_unreviewed)
    write_c3d(path, labels, points, valid, fps=rate, frames=session.frames, descriptions=marker_descriptions(labels))
    return path


def _caveat(session) -> str:
    if consecutive_frames(session):
        return ""
    return ("the project's frame numbers are not consecutive: a C3D reader times C3D frames one 1/fps apart, so "
            "its times are not frame / fps; the C3D's FLUOROGUI:FRAMES and FLUOROGUI:TIMES hold the true ones "
            "(.trc and .mot carry them too)")


FORMAT = register(ExportFormat(
    name="c3d", order=60, label="Anatomical markers (C3D)", default_name="{stem}.c3d", metavar="OUT.c3d",
    help="C3D: per component the anatomical origin and the points 10 mm along its x, y, z axes (world mm), one "
         "C3D frame per frame",
    short="C3D", timed=True, motion=True, caveat=_caveat,
    write=lambda session, path, options: [export_c3d(session, path, options.fps, options.include_unreviewed)]))
