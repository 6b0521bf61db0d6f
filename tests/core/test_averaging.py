"""Trials averaged (``core.knee.averaging``) on trials whose mean is known by hand: copies of
one curve shifted in time and sampled at other rates, copies offset up and down, and
trials that flex at different speeds."""
from __future__ import annotations

import numpy as np
import pytest

from fluorogui.core.knee.averaging import PERCENT, by_flexion, by_time, flexion_grid, flexion_phase, mean_curves


def curve(phase):
    """A smooth activity curve of the phase 0..1 (two quantities)."""
    phase = np.asarray(phase, dtype=float)
    return np.column_stack([60 * np.sin(np.pi * phase), 5 * np.cos(2 * np.pi * phase)])


def test_time_shifted_copies_at_other_frame_rates_average_to_the_curve():
    frames_a = np.arange(0, 101)  # 101 frames
    frames_b = np.arange(37, 37 + 2 * 80 + 1, 2)  # later, every other frame number, 81 frames
    frames_c = np.arange(500, 541)  # 41 frames
    trials = [by_time(f, curve((f - f[0]) / (f[-1] - f[0]))) for f in (frames_a, frames_b, frames_c)]
    mean = mean_curves(PERCENT, trials)
    # linear interpolation of a sine sampled every 2.5 % misses by at most h^2/8 * max|f''|
    assert np.nanmax(np.abs(mean.mean - curve(PERCENT / 100))) < 60 * np.pi ** 2 * 0.025 ** 2 / 8
    np.testing.assert_allclose(mean.mean[::5], curve(PERCENT[::5] / 100), atol=0.05)
    assert np.all(mean.n == 3)


def test_copies_offset_up_and_down_give_the_curve_and_a_known_sd():
    frames = np.arange(0, 51)
    base = curve(frames / 50)
    mean = mean_curves(PERCENT, [by_time(frames, base + 2.0), by_time(frames, base - 2.0)])
    np.testing.assert_allclose(mean.mean, by_time(frames, base), atol=1e-12)
    np.testing.assert_allclose(mean.sd, 2.0 * np.sqrt(2.0), atol=1e-12)  # sample SD (n - 1) of {+2, -2}


def test_frames_without_values_and_the_ends_of_the_activity():
    frames = np.arange(10, 31)
    values = curve((frames - 10) / 20)
    values[[0, 1]] = np.nan  # the first two frames unmatched: the activity starts at frame 12
    values[7] = np.nan
    out = by_time(frames, values)
    assert out[0, 0] == pytest.approx(values[2, 0]) and out[-1, 0] == pytest.approx(values[-1, 0])
    assert np.all(np.isfinite(out))
    one = mean_curves(PERCENT, [out, np.full_like(out, np.nan)])
    assert np.all(one.n == 1) and np.all(np.isnan(one.sd)) and np.allclose(one.mean, out)


def test_trials_flexing_at_different_speeds_average_by_flexion():
    """AP against flexion is the same function in each trial; they flex at different
    speeds, over different ranges, and extend again afterwards."""
    def trial(top, frames):
        t = np.linspace(0, 1, frames)
        flexion = top * np.sin(np.pi * t) ** 2 * (t < 0.5) + top * (t >= 0.5) * (1 - 0.5 * (t - 0.5))
        return flexion, np.column_stack([-0.1 * flexion + 0.001 * flexion ** 2])

    trials = [trial(90.0, 40), trial(110.0, 73), trial(100.0, 25)]
    grid = flexion_grid([f for f, _ in trials], step=1.0)
    assert grid[0] == 0 and grid[-1] == np.floor(min(f.max() for f, _ in trials)) == 89  # shared while flexing
    mean = mean_curves(grid, [by_flexion(f, v, grid) for f, v in trials])
    want = -0.1 * grid + 0.001 * grid ** 2
    # linear interpolation of a parabola between samples up to 13 deg apart: measured 0.020 (SD 0.021)
    np.testing.assert_allclose(mean.mean[:, 0], want, atol=0.04)
    assert np.nanmax(mean.sd) < 0.043


def test_the_flexing_phase_is_from_least_to_greatest_flexion():
    flexion = np.array([np.nan, 10, 5, 20, 60, 90, 70, 30])
    assert flexion_phase(flexion).tolist() == [2, 3, 4, 5]
    assert flexion_phase(flexion[::-1]).tolist() == [2, 3, 4, 5]  # an extension read in time order
    assert len(flexion_grid([np.array([0, 10.0]), np.array([20, 30.0])])) == 0  # no shared range
