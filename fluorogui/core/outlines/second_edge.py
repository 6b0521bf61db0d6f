"""A second edge just outside a component's rim: a bone's cortex beside the metal.

The rim fit (``core.outlines.rim``) explains the pixels around each outline point by the metal's
blurred profile over a background with a slope. Where a bone's edge runs within a few
pixels outside the outline, the background is not a slope: behind a cylinder-like bone
the path length grows like the square root of the distance inside its edge, so the light
falls like ``exp(-k sqrt(x))``, and a fit without it pulls whole stretches of the outline
inwards (a tray stretch beside a hand-drawn bone band, 4 px out: -0.19 to -0.26 px;
with the bone modelled -0.01 to -0.02 px).

``second_edges`` finds such an edge per outline point: the image's profile outwards
along the normal (0-12 px, averaged over three lines across it and over the point's
neighbours along the outline), the first change of more than ``JUMP`` over 2 px beyond
``FROM_PX`` (nearer, the rim's own blur), then the edge position and darkness ``k`` whose
blurred shape (``edge_shape``, times a level and a slope) fits that profile best. A
profile the shape does not fit (``MAX_MISFIT``: the component's own edge across a notch,
a stripe) is left alone. The rim fit then multiplies its background by that shape at
points whose edge lies within ``REACH_PX``, with ``k`` as measured here: a free
amplitude instead (tried: a square root added to the background) traded with the
boundary under noise where the edge lies beyond the fit's pixels.

Known limit: a dark ramp that starts at the outline and fades over a few pixels fits the
shape about as well as a bone; the rim fit then keeps part of such a stretch (13 of 30
points in a test), 0.3-0.7 px inside, where without the model the stray rule leaves
most of it out.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, map_coordinates

from fluorogui.core.outlines.profile_fit import least_squares, smooth_along

#: the outer profile: out to this far (px) from the point, sampled at this step
SCAN_PX, SCAN_STEP = 12.0, 0.25
#: an edge counts from this far out (px), where the averaged profile changes by more than
#: this share of its level over 2 px
FROM_PX, JUMP = 3.5, 0.06
#: the rim fit models an edge that lies at most this far (px) outside its point
REACH_PX = 6.0
#: outline points either side whose profiles are averaged, and whose edges smooth one's own
HALF_WINDOW = 8
#: the detection's blur (px): about the images' (the rim fits find 0.8-1.2)
DETECT_SIGMA = 1.0
#: where the found jump's steepest point may lie from the edge (px): the square root's
#: steepest blurred slope lies a little inside its edge
SHIFTS = np.arange(-0.5, 1.5 + 1e-9, 0.05)

#: the bone's darkening candidates: exp(-k sqrt(x)), x in px inside its edge (the X-ray
#: model's 14 mm shaft at 0.06/mm and 0.6 mm/px: k ~0.5)
K_GRID = np.geomspace(0.02, 1.5, 16)

#: a profile the bone's shape fits worse than this (RMS, as a share of its change over the
#: fit's window) is some other edge (the other component, a ramp): not modelled
MAX_MISFIT = 0.05

_FINE = 0.05
_SQRT_X = np.arange(-12.0, 40.0, _FINE)


def edge_shape(x: np.ndarray, k: np.ndarray, sigma: float) -> np.ndarray:
    """exp(-k sqrt(max(x, 0))) blurred by a Gaussian of ``sigma`` px, per row of ``x``
    (R, ...) with its own ``k`` (R,): the light a bone's edge lets through, x px inside it."""
    k = np.asarray(k, dtype=float).reshape(-1)
    table = gaussian_filter1d(np.exp(-k[:, None] * np.sqrt(np.clip(_SQRT_X, 0.0, None))[None, :]),
                              max(sigma, 1e-3) / _FINE, axis=1, mode="nearest")
    idx = np.clip((np.asarray(x, dtype=float) - _SQRT_X[0]) / _FINE, 0.0, len(_SQRT_X) - 1.001)
    i0 = np.floor(idx).astype(int)
    frac = idx - i0
    rows = np.arange(len(k)).reshape((-1,) + (1,) * (np.ndim(x) - 1))
    return table[rows, i0] * (1 - frac) + table[rows, i0 + 1] * frac


def _along_mean(values: np.ndarray, half_window: int) -> np.ndarray:
    """The mean of each row and its ``half_window`` neighbours either side (closed outline)."""
    if half_window <= 0 or len(values) <= 2 * half_window:
        return values
    padded = np.concatenate([values[-half_window:], values, values[:half_window]])
    total = np.cumsum(np.concatenate([np.zeros((1,) + values.shape[1:]), padded]), axis=0)
    width = 2 * half_window + 1
    return (total[width:] - total[:-width]) / width


def second_edges(image: np.ndarray, points: np.ndarray, normals: np.ndarray,
                 exclude: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per outline point (K, 2) with its outward unit normal (K, 2): how far out (px) a
    second edge lies, NaN where none is found within the scan (or the scan meets
    ``exclude``, another component), and how dark it is (k of ``edge_shape``)."""
    image = np.asarray(image, dtype=float)
    points, normals = np.asarray(points, dtype=float), np.asarray(normals, dtype=float)
    d = np.arange(0.0, SCAN_PX + 1e-9, SCAN_STEP)
    across = np.array([-1.0, 0.0, 1.0])
    tangent = np.column_stack([-normals[:, 1], normals[:, 0]])
    where = (points[:, None, None, :] + d[None, :, None, None] * normals[:, None, None, :]
             + across[None, None, :, None] * tangent[:, None, None, :])  # (K, D, 3, 2)
    coords = [where[..., 1].ravel(), where[..., 0].ravel()]
    samples = map_coordinates(image, coords, order=1, mode="nearest").reshape(where.shape[:3])
    profile = _along_mean(samples.mean(axis=2), HALF_WINDOW)  # (K, D)
    step = int(round(2.0 / SCAN_STEP))
    level = np.maximum(np.maximum(profile[:, :-step], profile[:, step:]), 1e-12)
    jump = np.abs(profile[:, step:] - profile[:, :-step]) / level > JUMP
    jump &= (d[:-step] >= FROM_PX)[None, :]
    candidate = jump.any(axis=1)
    if exclude is not None:  # a scan that meets another component sees its edge, not a bone's
        blocked = map_coordinates(np.asarray(exclude, dtype=float), coords, order=0, mode="constant")
        candidate &= blocked.reshape(len(points), -1).max(axis=1) <= 0
    first = np.argmax(jump, axis=1)
    edges, darkness = np.full(len(points), np.nan), np.full(len(points), np.nan)
    rows = np.flatnonzero(candidate)
    if len(rows):
        edges[rows], darkness[rows] = _fit_edges(profile[rows], d, first[rows], step)
    found = np.isfinite(edges)
    return (np.where(found, smooth_along(edges, HALF_WINDOW), np.nan),
            np.where(found, smooth_along(np.where(found, darkness, np.nan), HALF_WINDOW), np.nan))


def _fit_edges(profile: np.ndarray, d: np.ndarray, first: np.ndarray, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Where (and how dark) a bone's edge (``edge_shape``, times a level and a slope) fits
    each profile best, its edge ``SHIFTS`` from the steepest point of the jump found at
    ``first``, its k from ``K_GRID``."""
    rows = np.arange(len(profile))
    span = first[:, None] + np.arange(step + 1)[None, :]
    slope = np.abs(np.gradient(profile, axis=1))
    steepest = d[np.take_along_axis(span, np.argmax(slope[rows[:, None], span], axis=1)[:, None], 1)[:, 0]]
    edge = steepest[:, None] + SHIFTS[None, :]  # (R, C) candidates
    # fit the profile from 1 px within FROM_PX (the rim's blur is gone there) to 3 px past the candidate
    near = (d[None, None, :] >= FROM_PX - 1.0) & (d[None, None, :] <= edge[:, :, None] + 3.0)
    w = near.astype(float)
    v = profile[:, None, :] * w
    x = edge[:, :, None] - d[None, None, :]  # (R, C, D) px inside the candidate edge
    best = np.full((len(profile), len(K_GRID)), np.inf)
    where = np.zeros((len(profile), len(K_GRID)), dtype=int)
    for j, k in enumerate(K_GRID):
        shape = edge_shape(x.reshape(1, -1), np.array([k]), DETECT_SIGMA).reshape(x.shape)
        residual, _ = least_squares([shape * w, d[None, None, :] * shape * w], v, ridge=1e-12)
        residual = residual / np.maximum(w.sum(-1), 1.0)
        where[:, j] = np.argmin(residual, axis=1)
        best[:, j] = residual[rows, where[:, j]]
    j = np.argmin(best, axis=1)
    # between the grid's values: a parabola in log k through the best one and its neighbours
    jj = np.clip(j, 1, len(K_GRID) - 2)
    a, b, c = best[rows, jj - 1], best[rows, jj], best[rows, jj + 1]
    den = a - 2 * b + c
    ok = (jj == j) & np.isfinite(a + b + c) & (den > 0)
    shift = np.where(ok, 0.5 * (a - c) / np.where(ok, den, 1.0), 0.0)
    log_k = np.log(K_GRID[jj]) + np.clip(shift, -1, 1) * np.log(K_GRID[1] / K_GRID[0])
    # how well the shape fits: the RMS misfit as a share of the profile's change over the window
    chosen = edge[rows, where[rows, j]]
    inside = (d[None, :] >= FROM_PX - 1.0) & (d[None, :] <= chosen[:, None] + 3.0)
    span = np.array([np.ptp(p[m]) for p, m in zip(profile, inside)])
    misfit = np.sqrt(np.maximum(best[rows, j], 0.0)) / np.maximum(span, 1e-12)
    return np.where(misfit <= MAX_MISFIT, chosen, np.nan), np.where(ok, np.exp(log_k), K_GRID[j])
