"""A percentile near either end of an array, to the bit of ``np.percentile``, without
partitioning the whole array.

Canny's reference gradient (the 99.9th percentile of a crop's gradient magnitude) and the
field of view's darkest grey (the 0.5th percentile) need two neighbouring order statistics
of a large array. ``np.percentile`` partitions all of it; the statistics lie in a thin tail,
so here a strided sample suggests a threshold, only the values beyond it are sorted, and the
two statistics are read off those (they are the same values whatever the method). Then
numpy's own linear interpolation ("linear", Hyndman and Fan's 7th method, with a Python
float ``q``) is repeated step by step. Anything unusual (small arrays, other dtypes, a NaN,
a sample that misses the tail) falls back to ``np.percentile``.
"""
from __future__ import annotations

import math

import numpy as np

#: below this many values the whole array is cheap to partition
_MIN_SIZE = 4096
#: every how many values the sample that chooses the threshold takes one
_STRIDE = 16


def tail_percentile(values: np.ndarray, q: float) -> float:
    """``float(np.percentile(values, q))`` for a float32 or float64 array, computed from the
    tail of the array that holds the ``q``-th percentile."""
    values = np.asarray(values)
    n = values.size
    if n < _MIN_SIZE or values.dtype not in (np.float32, np.float64) or not 0.0 <= q <= 100.0:
        return float(np.percentile(values, q))
    # numpy's virtual index for the linear method, in the same operations
    virtual = (n - 1) * float(np.true_divide(q, 100))
    if virtual >= n - 1 or virtual < 0:
        return float(np.percentile(values, q))
    below = math.floor(virtual)
    gamma = virtual - below
    upper = below >= n // 2
    flat = values.reshape(-1)
    sample = flat[::_STRIDE]
    # the threshold leaves about twice the needed share of the sample beyond it, plus slack
    need = (n - below) if upper else (below + 2)
    beyond = min(len(sample) - 1, 2 * math.ceil(len(sample) * need / n) + 8)
    if upper:
        threshold = np.partition(sample, len(sample) - 1 - beyond)[len(sample) - 1 - beyond]
        if np.isnan(flat.max()):
            return float(np.percentile(values, q))
        tail = np.sort(flat[flat >= threshold])
        if len(tail) < need:
            return float(np.percentile(values, q))
        first = n - len(tail)  # the sorted position of tail[0]
        a, b = tail[below - first], tail[below + 1 - first]
    else:
        threshold = np.partition(sample, beyond)[beyond]
        if np.isnan(flat.max()):
            return float(np.percentile(values, q))
        tail = np.sort(flat[flat <= threshold])
        if len(tail) < need:
            return float(np.percentile(values, q))
        a, b = tail[below], tail[below + 1]
    # numpy's _lerp with a weak (Python float) weight: the arithmetic in the array's dtype
    diff = b - a
    result = a + diff * gamma
    if gamma >= 0.5:
        result = b - diff * (1 - gamma)
    return float(result)
