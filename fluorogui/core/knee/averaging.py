"""Trials averaged: each trial's curves normalised to the activity, then mean ± SD.

* **By time**: a trial runs from its first to its last frame with values, 0–100 % of the
  activity (frame numbers are proportional to time); each curve is interpolated linearly
  at every 1 % (``PERCENT``), NaN outside the frames it has values for.
* **By flexion**: a trial's phase between its least and its greatest flexion (in time
  order: the flexing phase, or the extending one reversed), each curve interpolated at
  every ``step`` degrees of the flexion range that all trials share.

The mean and the sample SD (n − 1) are taken at each point over the trials that have a
value there; ``n`` says how many.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PERCENT = np.linspace(0.0, 100.0, 101)


def _interpolate(x: np.ndarray, values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Each column of ``values`` (rows at increasing ``x``) at ``grid``; NaN outside the
    column's own finite values."""
    out = np.full((len(grid), values.shape[1]), np.nan)
    for k in range(values.shape[1]):
        ok = np.isfinite(values[:, k]) & np.isfinite(x)
        if np.count_nonzero(ok) < 2:
            continue
        xs, ys = x[ok], values[ok, k]
        inside = (grid >= xs[0] - 1e-9) & (grid <= xs[-1] + 1e-9)
        out[inside, k] = np.interp(grid[inside], xs, ys)
    return out


def by_time(frames, values) -> np.ndarray:
    """One trial's curves (``values``: rows per frame, columns per quantity) at 0–100 %
    of its activity; returns ``(len(PERCENT), columns)``."""
    frames = np.asarray(frames, dtype=float)
    values = np.asarray(values, dtype=float).reshape(len(frames), -1)
    order = np.argsort(frames, kind="stable")
    frames, values = frames[order], values[order]
    has = np.any(np.isfinite(values), axis=1)
    if np.count_nonzero(has) < 2:
        return np.full((len(PERCENT), values.shape[1]), np.nan)
    first, last = frames[has][0], frames[has][-1]
    percent = (frames - first) / (last - first) * 100.0
    return _interpolate(percent, values, PERCENT)


def flexion_phase(flexion) -> np.ndarray:
    """Indices (in time order) of a trial's phase from its least to its greatest flexion."""
    flexion = np.asarray(flexion, dtype=float)
    ok = np.flatnonzero(np.isfinite(flexion))
    if len(ok) < 2:
        return ok
    low, high = ok[np.argmin(flexion[ok])], ok[np.argmax(flexion[ok])]
    start, stop = min(low, high), max(low, high)
    return ok[(ok >= start) & (ok <= stop)]


def flexion_grid(flexions, step: float = 1.0) -> np.ndarray:
    """Every ``step`` degrees of the flexion range that every trial's phase covers (empty
    when they share none)."""
    lows, highs = [], []
    for flexion in flexions:
        flexion = np.asarray(flexion, dtype=float)
        phase = flexion[flexion_phase(flexion)]
        if len(phase) < 2:
            return np.empty(0)
        lows.append(phase.min())
        highs.append(phase.max())
    low, high = np.ceil(max(lows) / step) * step, np.floor(min(highs) / step) * step
    if high < low:
        return np.empty(0)
    return np.arange(low, high + step / 2, step)


def by_flexion(flexion, values, grid) -> np.ndarray:
    """One trial's curves at the flexion angles ``grid``, over its flexing phase."""
    flexion = np.asarray(flexion, dtype=float)
    values = np.asarray(values, dtype=float).reshape(len(flexion), -1)
    phase = flexion_phase(flexion)
    order = phase[np.argsort(flexion[phase], kind="stable")]
    return _interpolate(flexion[order], values[order], np.asarray(grid, dtype=float))


@dataclass(frozen=True)
class MeanCurves:
    """Curves of several trials on one axis.

    Attributes
    ----------
    x : numpy.ndarray of shape (k,)
        Percent of the activity, or flexion (degrees).
    trials : numpy.ndarray of shape (t, k, q)
        Each trial's curves (NaN where it has none).
    mean, sd : numpy.ndarray of shape (k, q)
        Over the trials with a value (SD with n − 1; NaN below two trials).
    n : numpy.ndarray of shape (k, q)
        How many trials have a value.
    """

    x: np.ndarray
    trials: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    n: np.ndarray


def mean_curves(x, curves) -> MeanCurves:
    """Mean ± SD of trials' normalised curves (each ``(len(x), q)``)."""
    trials = np.stack([np.asarray(c, dtype=float) for c in curves])
    n = np.count_nonzero(np.isfinite(trials), axis=0)
    total = np.nansum(trials, axis=0)
    mean = np.where(n > 0, total / np.maximum(n, 1), np.nan)
    squares = np.nansum((trials - mean[None]) ** 2, axis=0)
    sd = np.where(n > 1, np.sqrt(squares / np.maximum(n - 1, 1)), np.nan)
    return MeanCurves(np.asarray(x, dtype=float), trials, mean, sd, n)
