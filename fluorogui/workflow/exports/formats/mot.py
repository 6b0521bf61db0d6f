"""OpenSim motion (``.mot``): time and the six knee values, degrees and metres (``--mot``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fluorogui import __version__
from fluorogui.core.knee.kinematics import SIGN_CONVENTIONS
from fluorogui.core.status import Status
from fluorogui.io.files import check_output_file
from fluorogui.io.motion_files import frame_times, write_mot
from fluorogui.workflow.exports.registry import ExportFormat, register
from fluorogui.workflow.exports.timebase import require_frame_rate

MOT_COLUMNS = ("knee_flexion", "knee_varus", "knee_internal_rotation", "knee_medial_translation",
               "knee_anterior_translation", "knee_distraction")
MOT_METRES = (False, False, False, True, True, True)  # .mot holds translations in metres (OpenSim)


def mot_table(rows, include_unreviewed: bool = False) -> np.ndarray:
    """The six Grood–Suntay values per row as ``.mot`` holds them (degrees; translations in
    metres); NaN where a component is missing, or its pose is left out (see ``exports.tables``)."""
    table = np.full((len(rows), 6), np.nan)
    for i, row in enumerate(rows):
        if row.status == Status.MATCHED or (include_unreviewed and row.status == "needs_review"):
            table[i] = row.values.values()
    table[:, 3:] /= 1000.0
    return table


def export_mot(session, path, *, rows=None, fps: float | None = None, include_unreviewed: bool = False) -> Path:
    """OpenSim Storage: ``time`` and the six knee values named ``MOT_COLUMNS``."""
    path = check_output_file(path)
    rate = require_frame_rate(session, path, fps)
    rows = session.knee_rows() if rows is None else rows
    side = session.side or "right (assumed)"
    notes = [f"fluorogui {__version__} knee kinematics of {session.path.name if session.path else 'an unsaved project'}"
             f", {side} knee",
             "Units are S.I. units (second, meters): knee_medial_translation, knee_anterior_translation and "
             "knee_distraction in meters; knee_flexion, knee_varus and knee_internal_rotation in degrees",
             f"time is frame number / {rate:g} frames per second",
             f"{SIGN_CONVENTIONS}",
             "NaN where a component has no pose, or its pose was not matched or accepted"
             + (" (placed or flagged poses included)" if include_unreviewed else "")]
    write_mot(path, "knee_kinematics", list(MOT_COLUMNS), frame_times([r.frame for r in rows], rate),
              table=mot_table(rows, include_unreviewed), notes=notes)
    return path


FORMAT = register(ExportFormat(
    name="mot", order=80, label="Kinematics for OpenSim (.mot)", default_name="{stem}_knee.mot", metavar="OUT.mot",
    help="OpenSim motion: time and the six knee values (degrees, metres)", short=".mot", timed=True,
    kinematic=True, motion=True,
    write=lambda session, path, options: [export_mot(session, path, rows=options.rows, fps=options.fps,
                                                     include_unreviewed=options.include_unreviewed)]))
