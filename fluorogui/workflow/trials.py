"""Trials averaged: the kinematics and contact curves of several projects (trials,
subjects), normalised to the activity (0-100 % of time, or by flexion) and shown as
mean ± SD with each trial's curve (``core.knee.averaging``). Only matched frames enter a
trial's curves. Left and right knees average together: the kinematics keep their clinical
names on both sides and the contact points are mirrored to + lateral.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fluorogui import __version__
from fluorogui.core.knee.averaging import (
    PERCENT,
    MeanCurves,
    by_flexion,
    by_time,
    flexion_grid,
    mean_curves,
)
from fluorogui.core.knee.contact import CONTACT_SIGN_CONVENTIONS, LIFTOFF_MM
from fluorogui.core.knee.kinematics import KINEMATICS_COLUMNS, KINEMATICS_LABELS, SIGN_CONVENTIONS
from fluorogui.core.status import Status
from fluorogui.io.files import check_output_file
from fluorogui.io.pose_files import write_csv
from fluorogui.workflow.contact import contact_rows, session_contact_setup

NORMALIZATIONS = ("time", "flexion")
CONTACT_QUANTITIES = ("medial_y_mm", "lateral_y_mm", "medial_x_mm", "lateral_x_mm", "medial_z_mm", "lateral_z_mm")
GAP_QUANTITIES = ("medial_gap_mm", "lateral_gap_mm")
QUANTITY_LABELS = dict(zip(KINEMATICS_COLUMNS, (f"{a} ({u})" for a, u in
                                                zip(KINEMATICS_LABELS, ("°", "°", "°", "mm", "mm", "mm")))))
QUANTITY_LABELS.update({
    "medial_y_mm": "Medial condyle AP (mm)", "lateral_y_mm": "Lateral condyle AP (mm)",
    "medial_x_mm": "Medial condyle ML (mm)", "lateral_x_mm": "Lateral condyle ML (mm)",
    "medial_z_mm": "Medial condyle height (mm)", "lateral_z_mm": "Lateral condyle height (mm)",
    "medial_gap_mm": "Medial gap (mm)", "lateral_gap_mm": "Lateral gap (mm)",
})


@dataclass(frozen=True)
class Trial:
    """One trial's curves: frame numbers, flexion and ``values`` (frames × ``quantities``),
    NaN where a frame is not matched."""

    name: str
    frames: np.ndarray
    flexion: np.ndarray
    quantities: tuple[str, ...]
    values: np.ndarray


def trial_of_session(session, *, name: str | None = None, contact: bool = True, insert_mesh=None,
                     insert_to_tray=None, liftoff_mm: float = LIFTOFF_MM) -> Trial:
    """A session's kinematics (and contact, unless ``contact`` is False) as one trial."""
    knee = session.knee_rows()
    keep = np.array([r.status == Status.MATCHED for r in knee], dtype=bool)
    values = np.array([r.values.values() for r in knee], dtype=float).reshape(len(knee), 6)
    quantities = list(KINEMATICS_COLUMNS)
    if contact:
        setup = session_contact_setup(session, insert_mesh=insert_mesh, insert_to_tray=insert_to_tray,
                                      liftoff_mm=liftoff_mm)
        rows = contact_rows(session, setup, knee_rows=knee)
        points = np.array([[r.contact.medial.lowest[k], r.contact.lateral.lowest[k]] for r in rows for k in (1, 0, 2)]
                          ).reshape(len(rows), 6)  # the order of CONTACT_QUANTITIES
        values = np.column_stack([values, points])
        quantities += CONTACT_QUANTITIES
        if setup.insert is not None:
            gaps = np.array([[r.contact.medial.gap_mm, r.contact.lateral.gap_mm] for r in rows]).reshape(-1, 2)
            values = np.column_stack([values, gaps])
            quantities += GAP_QUANTITIES
    values[~keep] = np.nan
    label = name or (session.path.stem if session.path else "trial")
    return Trial(label, np.array([r.frame for r in knee], dtype=float), values[:, 0].copy(), tuple(quantities),
                 values)


@dataclass(frozen=True)
class Averaged:
    """Trials averaged: the curves, their quantities, the axis name (``percent`` or
    ``flexion_deg``) and the trials' names."""

    curves: MeanCurves
    quantities: tuple[str, ...]
    axis: str
    names: tuple[str, ...]


def average_trials(trials: list[Trial], normalize: str = "time", step_deg: float = 1.0) -> Averaged:
    """Mean ± SD of trials normalised by ``time`` (0-100 %) or ``flexion`` (every
    ``step_deg`` of the range they share).

    Raises
    ------
    ValueError
        Fewer than two trials, different quantities, an unknown normalisation, or (by
        flexion) no flexion range shared by every trial.
    """
    if normalize not in NORMALIZATIONS:
        raise ValueError(f"normalize must be 'time' or 'flexion', not {normalize!r}")
    if len(trials) < 2:
        raise ValueError("averaging needs two trials or more")
    quantities = trials[0].quantities
    if any(t.quantities != quantities for t in trials):
        shared = [q for q in quantities if all(q in t.quantities for t in trials)]
        trials = [Trial(t.name, t.frames, t.flexion, tuple(shared),
                        t.values[:, [t.quantities.index(q) for q in shared]]) for t in trials]
        quantities = tuple(shared)
    if normalize == "time":
        curves = mean_curves(PERCENT, [by_time(t.frames, t.values) for t in trials])
        return Averaged(curves, quantities, "percent", tuple(t.name for t in trials))
    grid = flexion_grid([t.flexion for t in trials], step_deg)
    if len(grid) < 2:
        spans = ", ".join(f"{t.name}: {np.nanmin(t.flexion):.0f}-{np.nanmax(t.flexion):.0f} deg"
                          if np.isfinite(t.flexion).any() else f"{t.name}: no matched frame" for t in trials)
        raise ValueError(f"the trials share no flexion range to average over ({spans})")
    keep = [k for k, q in enumerate(quantities) if q != "flexion_deg"]
    curves = mean_curves(grid, [by_flexion(t.flexion, t.values[:, keep], grid) for t in trials])
    return Averaged(curves, tuple(quantities[k] for k in keep), "flexion_deg", tuple(t.name for t in trials))


def mean_cells(averaged: Averaged) -> tuple[list[str], list[list]]:
    """The mean CSV's columns and rows, long: one row per point and quantity."""
    c = averaged.curves
    columns = [averaged.axis, "quantity", "n", "mean", "sd", *(f"trial_{i + 1}" for i in range(c.trials.shape[0]))]
    rows = []
    for k, quantity in enumerate(averaged.quantities):
        for i, x in enumerate(c.x):
            rows.append([float(x), quantity, int(c.n[i, k]), float(c.mean[i, k]), float(c.sd[i, k]),
                         *(float(v) for v in c.trials[:, i, k])])
    return columns, rows


def write_mean_csv(path, averaged: Averaged) -> Path:
    """Write the averaged curves (:func:`mean_cells`) with a header naming each trial."""
    path = check_output_file(path)
    axis = "percent of the activity (first to last matched frame)" if averaged.axis == "percent" else \
        "flexion (deg), over each trial's phase from its least to its greatest flexion"
    header = [f"fluorogui {__version__} trials averaged: mean and sample SD (n - 1) over the trials with a value",
              f"normalised by: {axis}", "units: mm and degrees", f"kinematics: {SIGN_CONVENTIONS}",
              f"contact: {CONTACT_SIGN_CONVENTIONS}", "only matched frames enter a trial's curves",
              *(f"trial_{i + 1}: {name}" for i, name in enumerate(averaged.names))]
    columns, rows = mean_cells(averaged)
    write_csv(path, header, columns, rows)
    return path


def save_mean_plot(path, averaged: Averaged) -> Path:
    """The mean ± SD figure (``contact_plot.draw_mean``) as PNG, SVG or PDF."""
    from fluorogui.workflow.contact_plot import save_mean_figure

    path = check_output_file(path)
    x_label = "% of the activity" if averaged.axis == "percent" else "flexion (°)"
    save_mean_figure(averaged.curves, [QUANTITY_LABELS.get(q, q) for q in averaged.quantities], x_label, path,
                     trial_names=averaged.names)
    return path
