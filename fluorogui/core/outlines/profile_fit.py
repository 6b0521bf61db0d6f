"""Numeric helpers the rim fit (``core.outlines.rim``) and the second-edge fit (``core.outlines.second_edge``)
share: batched linear least squares over per-point basis functions, a median along a
closed outline, the precision of the fits along it (the rim's point weights), a closed
outline's curvature, and the rule that leaves out fits pulled off by another edge."""
from __future__ import annotations

import numpy as np


def least_squares(basis: list[np.ndarray], v: np.ndarray, ridge: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Per (point, candidate): the residual of ``v`` (P, S, W) fitted by the weighted
    basis functions (each (P, S, W), or broadcasting to it) and their coefficients
    (P, S, len(basis)); ``ridge`` keeps a basis that is zero everywhere solvable."""
    if len(basis) == 3:
        return _least_squares_3(basis, v, ridge)
    normal = np.stack([np.stack([(a * b).sum(-1) for b in basis], -1) for a in basis], -2)
    rhs = np.stack([(a * v).sum(-1) for a in basis], -1)
    coef = np.linalg.solve(normal + ridge * np.eye(len(basis)), rhs[..., None])[..., 0]
    return (v * v).sum(-1) - (coef * rhs).sum(-1), coef


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...w,...w->...", *np.broadcast_arrays(a, b))


def _least_squares_3(basis: list[np.ndarray], v: np.ndarray, ridge: float) -> tuple[np.ndarray, np.ndarray]:
    """``least_squares`` of three basis functions: the symmetric normal equations solved
    by their cofactors (the rim fit's grid search solves millions of them; a batched
    ``np.linalg.solve`` took most of its time)."""
    a0, a1, a2 = basis
    n00, n01, n02 = _dot(a0, a0) + ridge, _dot(a0, a1), _dot(a0, a2)
    n11, n12, n22 = _dot(a1, a1) + ridge, _dot(a1, a2), _dot(a2, a2) + ridge
    r0, r1, r2 = _dot(a0, v), _dot(a1, v), _dot(a2, v)
    c00, c01, c02 = n11 * n22 - n12 * n12, n02 * n12 - n01 * n22, n01 * n12 - n02 * n11
    c11, c12, c22 = n00 * n22 - n02 * n02, n01 * n02 - n00 * n12, n00 * n11 - n01 * n01
    det = n00 * c00 + n01 * c01 + n02 * c02
    coef = np.stack([(c00 * r0 + c01 * r1 + c02 * r2) / det, (c01 * r0 + c11 * r1 + c12 * r2) / det,
                     (c02 * r0 + c12 * r1 + c22 * r2) / det], -1)
    fitted = coef[..., 0] * r0 + coef[..., 1] * r1 + coef[..., 2] * r2
    return (v * v).sum(-1) - fitted, coef


def smooth_along(values: np.ndarray, half_window: int) -> np.ndarray:
    """The median of each value of a closed outline's points and its ``half_window``
    neighbours either side, NaN left out (0 where a window holds no number). The rim's
    bias changes slowly along an outline, the noise of a single profile fit does not:
    the median keeps the first and drops most of the second."""
    values = np.asarray(values, dtype=float)
    if half_window <= 0 or len(values) <= 2 * half_window:
        return np.nan_to_num(values)
    padded = np.r_[values[-half_window:], values, values[:half_window]]
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half_window + 1)
    return np.nan_to_num(nanmedian_rows(windows))


def nanmedian_rows(windows: np.ndarray) -> np.ndarray:
    """``np.nanmedian(windows, axis=1)``, NaN for rows without a number, and no warning
    for those: the view threads run this side by side, and ``warnings.catch_warnings``
    changes the process's filters, so one thread leaving it let another's "All-NaN slice"
    warning through."""
    out = np.full(len(windows), np.nan)
    some = ~np.isnan(windows).all(axis=1)
    if some.any():
        out[some] = np.nanmedian(windows[some], axis=1)
    return out


#: points either side whose fits measure a point's precision (``precision_weights``)
PRECISION_HALF_WINDOW = 16
#: px: the least spread a stretch is credited with, below the steepest rims' 0.05 px (10th
#: percentile over the smaller femur's points, 8 noise draws), so no stretch takes over a match
PRECISION_FLOOR_PX = 0.02
#: weights are kept within this factor either side of their mean. At 20x the steep
#: stretches that then set the pose leaned the femur +0.016 deg in alpha (their own small
#: biases, not noise: the weights of one draw gave the same lean on another draw's outline);
#: at 5x +0.007, its beta / gamma spread still 0.4 / 0.7 of the even weights' (12 draws, ad hoc)
PRECISION_RANGE = 5.0


def precision_weights(found: np.ndarray, half_window: int = PRECISION_HALF_WINDOW) -> np.ndarray:
    """Per outline point, the inverse variance (relative, mean 1) of where the rim's fits
    put the boundary about it: 1 / s^2, s the robust spread (1.4826 x the median absolute
    deviation) of the ``found`` boundaries (px from the model boundary, NaN: no fit) of the
    point and its ``half_window`` neighbours either side. Where the metal thickens gently
    the profile's minimum is shallow and the fits scatter three times as far as on a steep
    rim (0.18 against 0.06 px, the least and most curved quarters of the smaller femur's
    points at 60 deg, 8 noise draws at the truth); an even weight lets those stretches set
    the pose. The scatter itself is the measure, not the curvature of each fit's residual:
    that overstated the difference (6.7x in SD between the same quarters) and needs a noise
    model; the scatter also takes down stretches spoiled by another edge."""
    found = np.asarray(found, dtype=float)
    if np.isfinite(found).sum() < 8:
        return np.ones(len(found))
    half = min(half_window, (len(found) - 1) // 2)
    padded = np.r_[found[-half:], found, found[:half]] if half else found
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    centre = nanmedian_rows(windows)
    spread = 1.4826 * nanmedian_rows(np.abs(windows - centre[:, None]))
    spread = np.where(np.isfinite(spread), spread, np.nanmedian(spread))
    w = 1.0 / np.maximum(spread, PRECISION_FLOOR_PX) ** 2
    w = np.clip(w / w.mean(), 1.0 / PRECISION_RANGE, PRECISION_RANGE)
    return w / w.mean()


def outline_curvature(closed: np.ndarray, normals: np.ndarray, half_px: float = 2.0) -> np.ndarray:
    """Signed curvature (1/px) of a closed, evenly spaced polyline at its vertices, positive
    where it bends towards the inside (away from the outward ``normals``): from the second
    difference over ``half_px`` either side, which also smooths a mesh silhouette's facets."""
    p = np.asarray(closed, dtype=float)
    step = float(np.median(np.linalg.norm(np.diff(p, axis=0), axis=1))) if len(p) > 1 else 1.0
    k = int(min(max(1, round(half_px / max(step, 1e-9))), (len(p) - 1) // 2))
    if k < 1:
        return np.zeros(len(p))
    ahead, behind = np.roll(p, -k, axis=0), np.roll(p, k, axis=0)
    h2 = np.linalg.norm(ahead - p, axis=1) * np.linalg.norm(p - behind, axis=1)
    return -np.einsum("ij,ij->i", ahead - 2 * p + behind, normals) / np.maximum(h2, 1e-12)


#: a stray lies farther than this many robust SDs (and this many px) from the outline's
#: median offset to the model boundary
STRAY_SCALES, STRAY_PX = 5.0, 0.6


def strays(offsets: np.ndarray) -> np.ndarray:
    """True for points whose offset (px) from the model boundary at the matched pose lies
    far from the outline's median one: ``STRAY_SCALES`` robust SDs (1.4826 x the median
    absolute deviation) and at least ``STRAY_PX``. Next to a bone's edge the profile fit
    is pulled by a pixel or two along a whole stretch; elsewhere it varies by tenths."""
    finite = np.isfinite(offsets)
    if finite.sum() < 8:
        return np.zeros(len(offsets), dtype=bool)
    centre = np.median(offsets[finite])
    scale = 1.4826 * np.median(np.abs(offsets[finite] - centre))
    far = np.zeros(len(offsets), dtype=bool)
    far[finite] = np.abs(offsets[finite] - centre) > max(STRAY_PX, STRAY_SCALES * scale)
    return far
