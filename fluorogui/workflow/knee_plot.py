"""The kinematics figure: the six joint values against frame or flexion, with frames that
need review marked, residuals and SD bands where the matches give them. Built on a plain
matplotlib ``Figure`` (no pyplot, no Qt), so the app embeds the same drawing that
``fluorogui export --plot`` saves."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from fluorogui.core.knee.kinematics import KINEMATICS_COLUMNS, KINEMATICS_LABELS

UNITS = ("°", "°", "°", "mm", "mm", "mm")
REVIEW_COLOUR = "#d62728"
LINE_COLOUR = "#1f77b4"


def kinematics_arrays(rows) -> dict[str, np.ndarray]:
    """Columns of the rows as arrays: frame, the six values, needs-review mask, residual."""
    frames = np.array([r.frame for r in rows], dtype=float)
    values = np.array([r.values.values() for r in rows], dtype=float).reshape(len(rows), 6)
    review = np.array([r.status == "needs_review" for r in rows], dtype=bool)
    sd = np.array([r.sd for r in rows], dtype=float).reshape(len(rows), 6)
    residual = np.full(len(rows), np.nan)
    for i, r in enumerate(rows):
        objectives = [rec.match.objective_mm for rec in r.records.values() if rec is not None and rec.match is not None]
        if objectives:
            residual[i] = max(objectives)
    return {"frame": frames, "values": values, "review": review, "residual": residual, "sd": sd}


def _flagged(ax, x, y, trusted) -> None:
    """Frames that need review: red rings. The axis range follows the matched frames, so a
    wrong pose does not flatten the curves; rings beyond it sit on the edge as arrows."""
    finite = trusted[np.isfinite(trusted)]
    if len(finite):
        lo, hi = float(finite.min()), float(finite.max())
        pad = max(0.12 * (hi - lo), 0.05)
        lo, hi = lo - pad, hi + pad
        ax.set_ylim(lo, hi)
    else:
        lo, hi = -np.inf, np.inf
    ok = np.isfinite(y)
    inside = ok & (y >= lo) & (y <= hi)
    if inside.any():
        ax.plot(x[inside], y[inside], "o", mfc="none", mec=REVIEW_COLOUR, ms=6)
    for mask, edge, marker in ((ok & (y > hi), hi, "^"), (ok & (y < lo), lo, "v")):
        if mask.any():
            ax.plot(x[mask], np.full(mask.sum(), edge), marker, color=REVIEW_COLOUR, ms=6, clip_on=False)


def _x_range(ax, x, *, frames: bool) -> None:
    """An x axis that spans the session's frames (or the flexions drawn), at least two
    frames or one degree wide: matplotlib's autoscale around a single point gives ±0.05 and
    ticks that overlap."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if frames:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    if not len(x):
        return
    lo, hi = float(x.min()), float(x.max())
    least = 2.0 if frames else 1.0
    if hi - lo < least:
        middle = 0.5 * (lo + hi)
        lo, hi = middle - least / 2, middle + least / 2
    pad = 0.5 if frames else 0.04 * (hi - lo)
    ax.set_xlim(lo - pad, hi + pad)


def draw_kinematics(figure: Figure, rows, *, side: str = "right", against: str = "frame", title: str = "",
                    current_frame: int | None = None, colours: tuple[str, str, str] | None = None) -> list:
    """Draw on ``figure`` (cleared first); returns the seven axes (six values, residual).

    Each axes' ``gid`` is its column name, so a click can be mapped back to a frame.
    ``colours`` (background, plot area, text) follow an app's theme; default: matplotlib's.
    """
    figure.clear()
    figure.set_layout_engine("constrained")
    data = kinematics_arrays(rows)
    x = data["frame"] if against == "frame" else data["values"][:, 0]
    x_label = "frame" if against == "frame" else "flexion (°)"
    grid = figure.add_gridspec(4, 2, height_ratios=[1, 1, 1, 0.7])
    axes = []
    for k, (column, label, unit) in enumerate(zip(KINEMATICS_COLUMNS, KINEMATICS_LABELS, UNITS)):
        ax = figure.add_subplot(grid[k % 3, k // 3])
        ax.set_gid(column)
        y = data["values"][:, k]
        review = data["review"]
        order = np.argsort(x, kind="stable") if against != "frame" else np.arange(len(x))
        order = order[~review[order]]  # the line joins the frames that do not need review
        trusted = np.where(review, np.nan, y)
        ax.plot(x[order], y[order], "-", color=LINE_COLOUR, lw=1.2, marker=".", ms=4, picker=5)
        band = data["sd"][order, k]
        if np.isfinite(band).any():  # ±2 SD from the matches' own uncertainty
            ax.fill_between(x[order], y[order] - 2 * band, y[order] + 2 * band, color=LINE_COLOUR, alpha=0.2, lw=0)
        _flagged(ax, x[review], y[review], trusted)
        if current_frame is not None and against == "frame":
            ax.axvline(current_frame, color="0.5", lw=0.8, ls="--")
        _x_range(ax, data["frame"] if against == "frame" else x, frames=against == "frame")
        ax.set_title(f"{label} ({unit})", fontsize=8, pad=2)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
        axes.append(ax)
    ax = figure.add_subplot(grid[3, :])
    ax.set_gid("residual_mm")
    ax.plot(data["frame"], data["residual"], "-", color="0.5", lw=1.0, marker=".", ms=3, picker=5)
    if data["review"].any():
        ax.plot(data["frame"][data["review"]], data["residual"][data["review"]], "o", mfc="none",
                mec=REVIEW_COLOUR, ms=6)
    ax.set_title("Worst match residual per frame (mm); red rings: needs review (arrows: beyond the axis)",
                 fontsize=8, pad=2)
    ax.set_xlabel("frame", fontsize=7)
    _x_range(ax, data["frame"], frames=True)
    ax.tick_params(labelsize=7)
    ax.grid(True, alpha=0.3)
    axes.append(ax)
    for ax in axes[2::3][:2]:
        ax.set_xlabel(x_label, fontsize=7)
    heading = f"Knee kinematics ({side} knee; tibia relative to femur, Grood & Suntay)"
    figure.suptitle(f"{title}: {heading}" if title else heading, fontsize=9)
    apply_colours(figure, axes, colours)
    return axes


def apply_colours(figure: Figure, axes, colours: tuple[str, str, str] | None) -> None:
    """Give a drawn figure an app theme's ``colours`` (background, plot area, text); None
    leaves matplotlib's."""
    if colours is None:
        return
    background, area, text = colours
    figure.set_facecolor(background)
    for words in figure.texts:  # the title
        words.set_color(text)
    for ax in axes:
        ax.set_facecolor(area)
        ax.title.set_color(text)
        ax.xaxis.label.set_color(text)
        ax.yaxis.label.set_color(text)
        ax.tick_params(colors=text)
        for spine in ax.spines.values():
            spine.set_color(text)


def save_kinematics_figure(rows, path, *, side: str = "right", against: str = "frame", title: str = "") -> None:
    """Write the figure as PNG, SVG or PDF (by the suffix), atomically."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    figure = Figure(figsize=(10, 8), dpi=120)
    FigureCanvasAgg(figure)
    draw_kinematics(figure, rows, side=side, against=against, title=title)
    save_figure(figure, path)


def save_figure(figure: Figure, path) -> None:
    """Write a figure as PNG, SVG or PDF (by the suffix), atomically, as an ordinary new
    file (mode by the umask)."""
    import os
    import tempfile
    from pathlib import Path

    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # an ordinary new file, not mkstemp's private 0600
    try:
        figure.savefig(tmp, format=path.suffix.lstrip(".").lower())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
