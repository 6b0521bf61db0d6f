"""Medians along an outline over stretches without a number: no warning, whatever another
thread does with the warning filters (``core.outlines.profile_fit.nanmedian_rows``).

The view threads run the rim fit side by side, and ``warnings.catch_warnings`` changes the
process's filters: a thread leaving it restored them while another was inside, and an
"All-NaN slice" warning came through on real frames. The tests take that other thread's
part by making ``catch_warnings`` do nothing, with every warning an error."""
from __future__ import annotations

import contextlib
import warnings

import numpy as np
import pytest

from fluorogui.core.outlines import profile_fit
from fluorogui.core.outlines.profile_fit import nanmedian_rows, precision_weights, smooth_along


@pytest.fixture
def filters_not_kept(monkeypatch):
    """Every warning an error, and ``catch_warnings`` a no-op (another thread restored the filters);
    the filters are restored afterwards by the real ``catch_warnings``, taken before the patch."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        monkeypatch.setattr(warnings, "catch_warnings", lambda *a, **k: contextlib.nullcontext())
        yield


def _outline_with_a_gap(n: int = 200, gap: slice = slice(50, 90)) -> np.ndarray:
    values = np.random.default_rng(3).normal(0.0, 0.2, n)
    values[gap] = np.nan  # 40 points without a fit: longer than any window here
    return values


def test_rows_without_a_number_give_nan_and_the_others_their_median(filters_not_kept):
    rows = np.array([[1.0, np.nan, 3.0], [np.nan, np.nan, np.nan], [2.0, 5.0, -1.0]])
    out = nanmedian_rows(rows)
    assert out[0] == 2.0 and np.isnan(out[1]) and out[2] == 2.0


def test_smoothing_across_a_gap_is_the_windows_median_and_zero_where_none_has_a_number(filters_not_kept):
    values = _outline_with_a_gap()
    out = smooth_along(values, 8)
    padded = np.r_[values[-8:], values, values[:8]]
    for i in range(len(values)):
        window = padded[i:i + 17]
        expected = 0.0 if np.isnan(window).all() else np.median(window[~np.isnan(window)])
        assert out[i] == expected
    assert np.all(out[66:74] == 0.0)  # the middle of the gap


def test_precision_weights_over_a_gap_without_a_warning(filters_not_kept):
    w = precision_weights(_outline_with_a_gap())
    assert np.all(np.isfinite(w)) and w.mean() == pytest.approx(1.0)
    assert w.max() / w.min() <= profile_fit.PRECISION_RANGE ** 2 * 1.0001  # clipped either side of the mean
