"""OpenSim marker file (``.trc``): the C3D's markers, Frame# the project's frame number (``--trc``)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.io.files import check_output_file
from fluorogui.io.motion_files import frame_times, write_trc
from fluorogui.workflow.exports.markers import marker_table
from fluorogui.workflow.exports.registry import ExportFormat, register
from fluorogui.workflow.exports.timebase import require_frame_rate


def export_trc(session, path, fps: float | None = None, include_unreviewed: bool = False) -> Path:
    """OpenSim marker file: the C3D's markers, Frame# the project's frame number, Time = frame / fps."""
    path = check_output_file(path)
    rate = require_frame_rate(session, path, fps)
    labels, points, valid = marker_table(session, include_unreviewed)
    write_trc(path, labels, session.frames, frame_times(session.frames, rate), points=points, valid=valid, fps=rate)
    return path


FORMAT = register(ExportFormat(
    name="trc", order=70, label="Anatomical markers for OpenSim (.trc)", default_name="{stem}.trc",
    metavar="OUT.trc", help="OpenSim markers: the C3D's markers", short=".trc", timed=True, motion=True,
    write=lambda session, path, options: [export_trc(session, path, options.fps, options.include_unreviewed)]))
