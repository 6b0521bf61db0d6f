"""The kinematics figure, PNG, SVG or PDF, against frame or flexion (``--plot``)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.io.errors import InputError
from fluorogui.io.files import check_output_file
from fluorogui.workflow.exports.registry import ExportFormat, register

SUFFIXES = (".png", ".svg", ".pdf")


def export_plot(session, path, against: str = "frame", rows=None) -> Path:
    from fluorogui.workflow.knee_plot import save_kinematics_figure

    path = check_output_file(path)
    if path.suffix.lower() not in SUFFIXES:
        raise InputError(path, FORMAT.suffix_problem)
    save_kinematics_figure(session.knee_rows() if rows is None else rows, path, side=session.side or "right",
                           against=against, title=session.path.stem if session.path else "")
    return path


FORMAT = register(ExportFormat(
    name="plot", order=50, label="Kinematics figure (PNG)", default_name="{stem}_kinematics.png",
    metavar="OUT.png|svg|pdf", help="the kinematics figure", short="figure", kinematic=True, suffixes=SUFFIXES,
    suffix_problem="the figure must be .png, .svg or .pdf",
    write=lambda session, path, options: [export_plot(session, path, options.against, options.rows)]))
