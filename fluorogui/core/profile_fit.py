"""Numeric helpers the rim fit (``core.rim``) and the second-edge fit (``core.second_edge``)
share: batched linear least squares over per-point basis functions, and a median along a
closed outline."""
from __future__ import annotations

import warnings

import numpy as np


def least_squares(basis: list[np.ndarray], v: np.ndarray, ridge: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Per (point, candidate): the residual of ``v`` (P, S, W) fitted by the weighted
    basis functions (each (P, S, W)) and their coefficients (P, S, len(basis)); ``ridge``
    keeps a basis that is zero everywhere solvable."""
    normal = np.stack([np.stack([(a * b).sum(-1) for b in basis], -1) for a in basis], -2)
    rhs = np.stack([(a * v).sum(-1) for a in basis], -1)
    coef = np.linalg.solve(normal + ridge * np.eye(len(basis)), rhs[..., None])[..., 0]
    return (v * v).sum(-1) - (coef * rhs).sum(-1), coef


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
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # windows without a number
        out = np.nanmedian(windows, axis=1)
    return np.nan_to_num(out)
