"""The contact figures, on plain matplotlib ``Figure`` objects (no pyplot, no Qt), so the app
can embed the same drawing a command saves:

* ``draw_contact``: the classic contact plot, each condyle's anterior-posterior position
  on the tray against flexion (medial and lateral), lift-off marked; beside it the tray
  seen from above with both condyles' paths and the pivot.
* ``draw_mean``: trials averaged, one panel per quantity, mean ± SD with each trial's
  curve beside it.
"""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from fluorogui.workflow.knee_plot import REVIEW_COLOUR, apply_colours, save_figure

CONDYLE_COLOURS = {"medial": "#1f77b4", "lateral": "#ff7f0e"}
LIFTOFF_COLOUR = "#d62728"


def contact_arrays(rows) -> dict[str, np.ndarray]:
    """Columns of contact rows: frame, flexion, each condyle's points (n, 3), lift-off
    per condyle, needs-review mask."""
    out = {"frame": np.array([r.frame for r in rows], dtype=float),
           "flexion": np.array([r.flexion_deg for r in rows], dtype=float),
           "review": np.array([r.status == "needs_review" for r in rows], dtype=bool)}
    for name in ("medial", "lateral"):
        out[name] = np.array([getattr(r.contact, name).lowest for r in rows], dtype=float).reshape(-1, 3)
        out[f"{name}_liftoff"] = np.array([r.contact.liftoff in (name, "both") for r in rows], dtype=bool)
    return out


def draw_contact(figure: Figure, rows, *, side: str = "right", title: str = "", pivot=None,
                 stacked: bool = False, current_frame: int | None = None,
                 colours: tuple[str, str, str] | None = None) -> list:
    """Draw on ``figure`` (cleared first); returns the two axes (AP against flexion, the
    tray from above). ``pivot``: a ``core.knee.contact.Pivot`` to mark on the tray;
    ``stacked``: one above the other (a narrow panel), else side by side;
    ``current_frame``: marked on both; ``colours``: as ``knee_plot.draw_kinematics``."""
    figure.clear()
    figure.set_layout_engine("constrained")
    data = contact_arrays(rows)
    grid = (figure.add_gridspec(2, 1, height_ratios=[1.2, 1]) if stacked
            else figure.add_gridspec(1, 2, width_ratios=[1.5, 1]))
    ap, tray = figure.add_subplot(grid[0]), figure.add_subplot(grid[1])
    ap.set_gid("contact_ap")
    tray.set_gid("contact_tray")
    flexion = data["flexion"]
    for name, colour in CONDYLE_COLOURS.items():
        points, lifted = data[name], data[f"{name}_liftoff"]
        good = np.isfinite(points[:, 1]) & np.isfinite(flexion) & ~data["review"]
        order = np.flatnonzero(good)
        ap.plot(flexion[order], points[order, 1], "-", marker=".", ms=4, lw=1.2, color=colour, label=name)
        mark = lifted & np.isfinite(points[:, 1])
        if mark.any():
            ap.plot(flexion[mark], points[mark, 1], "^", color=LIFTOFF_COLOUR, ms=6, mfc="none")
        review = data["review"] & np.isfinite(points[:, 1])
        if review.any():
            ap.plot(flexion[review], points[review, 1], "o", mfc="none", mec=REVIEW_COLOUR, ms=6)
        tray.plot(points[good, 0], points[good, 1], "-", marker=".", ms=3, lw=1.0, color=colour)
    ap.set_xlabel("flexion (°)", fontsize=8)
    ap.set_ylabel("anterior-posterior position on the tray (mm; + anterior)", fontsize=8)
    ap.set_title("Condyles' lowest points against flexion (red triangles: lift-off; rings: needs review)",
                 fontsize=8, pad=2)
    ap.legend(fontsize=7, loc="best")
    both = np.isfinite(data["medial"][:, 0]) & np.isfinite(data["lateral"][:, 0]) & ~data["review"]
    for i in np.flatnonzero(both)[:: max(1, int(np.count_nonzero(both) // 8))]:
        tray.plot([data["medial"][i, 0], data["lateral"][i, 0]], [data["medial"][i, 1], data["lateral"][i, 1]],
                  "-", color="0.6", lw=0.6)
    if pivot is not None and np.isfinite(pivot.x_mm):
        tray.plot([pivot.x_mm], [pivot.y_mm], "*", color="k", ms=11,
                  label=f"pivot ({pivot.kind}, {pivot.frames_used} frames)")
        tray.legend(fontsize=7, loc="best")
    tray.axvline(0, color="0.8", lw=0.8)
    tray.set_aspect("equal", adjustable="datalim")
    tray.set_xlabel("medial − / lateral + (mm)", fontsize=8)
    tray.set_ylabel("posterior − / anterior + (mm)", fontsize=8)
    tray.set_title("The tray from above: condyle paths, lines joining them", fontsize=8, pad=2)
    for ax in (ap, tray):
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    now = np.flatnonzero(data["frame"] == current_frame) if current_frame is not None else []
    for i in now:
        for name in ("medial", "lateral"):
            ap.plot([flexion[i]], [data[name][i, 1]], "o", color="k", ms=7, mfc="none", mew=1.4)
            tray.plot([data[name][i, 0]], [data[name][i, 1]], "o", color="k", ms=7, mfc="none", mew=1.4)
    heading = f"Condylar contact ({side} knee; tibial frame, + lateral, + anterior)"
    figure.suptitle(f"{title}: {heading}" if title else heading, fontsize=9)
    apply_colours(figure, [ap, tray], colours)
    return [ap, tray]


def save_contact_figure(rows, path, *, side: str = "right", title: str = "", pivot=None) -> None:
    """Write the contact figure as PNG, SVG or PDF (by the suffix), atomically."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    figure = Figure(figsize=(10, 5), dpi=120)
    FigureCanvasAgg(figure)
    draw_contact(figure, rows, side=side, title=title, pivot=pivot)
    save_figure(figure, path)


def draw_mean(figure: Figure, curves, labels, x_label: str, *, trial_names=(), title: str = "") -> list:
    """Mean ± SD of averaged trials (``core.knee.averaging.MeanCurves``), one panel per
    quantity (``labels``), each trial's curve in grey beside it; returns the axes."""
    figure.clear()
    figure.set_layout_engine("constrained")
    count = len(labels)
    columns = 3 if count > 4 else 2
    rows = int(np.ceil(count / columns))
    axes = []
    for k, label in enumerate(labels):
        ax = figure.add_subplot(rows, columns, k + 1)
        for t in range(curves.trials.shape[0]):
            ax.plot(curves.x, curves.trials[t, :, k], "-", color="0.65", lw=0.7,
                    label="each trial" if t == 0 else None)
        mean, sd = curves.mean[:, k], curves.sd[:, k]
        ax.fill_between(curves.x, mean - sd, mean + sd, color="#1f77b4", alpha=0.25, lw=0, label="± SD")
        ax.plot(curves.x, mean, "-", color="#1f77b4", lw=1.6, label="mean")
        ax.set_title(label, fontsize=8, pad=2)
        ax.set_xlabel(x_label, fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
        axes.append(ax)
    if axes:
        axes[0].legend(fontsize=6, loc="best")
    names = ", ".join(trial_names)
    heading = f"Trials averaged ({curves.trials.shape[0]}: {names})" if names else "Trials averaged"
    figure.suptitle(f"{title}: {heading}" if title else heading, fontsize=9)
    return axes


def save_mean_figure(curves, labels, x_label: str, path, *, trial_names=()) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    rows = int(np.ceil(len(labels) / (3 if len(labels) > 4 else 2)))
    figure = Figure(figsize=(11, 2.6 * rows + 0.6), dpi=120)
    FigureCanvasAgg(figure)
    draw_mean(figure, curves, labels, x_label, trial_names=trial_names)
    save_figure(figure, path)
