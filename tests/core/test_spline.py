"""Periodic outline splines and the point-to-spline distance of Eq. (4). Their speed
(closest points, self-intersection): benchmarks/bench_budgets.py."""
import json

import numpy as np
import pytest

from fluorogui.core.outlines.spline import (
    OutlineError,
    OutlineSpline,
    first_self_intersection,
    resample_closed_polyline,
    validate_outline,
)

CENTRE, RADIUS = np.array([300.0, 240.0]), 80.0


def circle(n, radius=RADIUS, centre=CENTRE, phase=0.0):
    th = phase + np.linspace(0, 2 * np.pi, n, endpoint=False)
    return centre + radius * np.column_stack([np.cos(th), np.sin(th)])


@pytest.fixture(scope="module")
def circle_spline():
    return OutlineSpline.fit(circle(300))


def random_queries(n, rng, spread=30.0):
    th = rng.uniform(0, 2 * np.pi, n)
    r = RADIUS + rng.uniform(-spread, spread, n)
    return CENTRE + r[:, None] * np.column_stack([np.cos(th), np.sin(th)]), r


@pytest.mark.parametrize("method", ["closest", "closest_secant"])
def test_distances_to_circle(circle_spline, method):
    q, r = random_queries(2000, np.random.default_rng(0))
    d, foot, normal, t = getattr(circle_spline, method)(q)
    np.testing.assert_allclose(d, np.abs(r - RADIUS), atol=1e-3)
    radial = (foot - CENTRE) / np.linalg.norm(foot - CENTRE, axis=1, keepdims=True)
    np.testing.assert_allclose(normal, radial, atol=1e-3)  # unit normals point outwards
    np.testing.assert_allclose(circle_spline.evaluate(t), foot, atol=1e-9)
    assert np.all((t >= circle_spline.t_range[0]) & (t < circle_spline.t_range[1]))


def test_closest_is_exact_on_a_wavy_outline():
    th = np.linspace(0, 2 * np.pi, 900, endpoint=False)
    r = 150 + 20 * np.sin(5 * th) + 5 * np.cos(13 * th)
    spline = OutlineSpline.fit(np.column_stack([500 + r * np.cos(th), 500 + r * np.sin(th)]))
    rng = np.random.default_rng(1)
    t_true = rng.uniform(*spline.t_range, 3000)
    foot = spline.evaluate(t_true)
    tangent = spline.derivative(t_true)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]]) / np.linalg.norm(tangent, axis=1)[:, None]
    offset = rng.uniform(-3, 3, 3000)  # small enough that foot is the nearest point
    d, _, _, _ = spline.closest(foot + offset[:, None] * normal)
    np.testing.assert_allclose(d, np.abs(offset), atol=1e-4)


def test_spline_interpolates_and_keeps_length(circle_spline):
    pts = circle(300)
    d, _, _, _ = circle_spline.closest(pts)
    assert d.max() < 1e-9  # s = 0: through the points, no shrinkage
    assert abs(circle_spline.length_px - 2 * np.pi * RADIUS) < 1e-3
    t0, t1 = circle_spline.t_range
    assert t0 == 0.0 and abs(t1 - 300 * 2 * RADIUS * np.sin(np.pi / 300)) < 1e-9
    np.testing.assert_allclose(circle_spline.evaluate([t0 + 1.0]), circle_spline.evaluate([t1 + 1.0]), atol=1e-9)


def test_smoothing_does_not_shrink_a_noisy_circle():
    rng = np.random.default_rng(4)
    pts = circle(600) + rng.normal(0, 0.05, (600, 2))
    spline = OutlineSpline.fit(pts, smoothing=0.05)
    radius = np.linalg.norm(spline.sample(2000) - CENTRE, axis=1)
    assert abs(radius.mean() - RADIUS) < 0.01


def test_sample_is_equally_spaced(circle_spline):
    pts = circle_spline.sample(60)
    steps = np.linalg.norm(np.diff(np.vstack([pts, pts[:1]]), axis=0), axis=1)
    assert pts.shape == (60, 2) and np.ptp(steps) < 1e-6


def test_sample_params_are_where_the_samples_lie():
    """The matcher takes its image samples' outline positions from ``sample_params`` instead
    of searching each sample's closest point again: they must be the same parameters."""
    wave = np.column_stack([np.zeros(300), 6 * np.sin(np.linspace(0, 6 * np.pi, 300))])
    spline = OutlineSpline.fit(circle(300) + wave)
    spline.gaps = np.array([[40.0, 90.0]])
    for skip in (False, True):
        t = spline.sample_params(200, skip_gaps=skip)
        np.testing.assert_array_equal(spline.evaluate(t), spline.sample(200, skip_gaps=skip))
        assert np.all((t >= spline.t_range[0]) & (t < spline.t_range[1]))
        np.testing.assert_allclose(spline.closest(spline.evaluate(t))[3], t, atol=1e-6)
    assert len(spline.sample_params(200, skip_gaps=True)) < 200  # the gap's samples left out


def test_duplicate_and_closing_points_are_ignored():
    pts = circle(40)
    with_duplicates = np.vstack([pts[:10], pts[9:10], pts[10:], pts[:1]])
    a, b = OutlineSpline.fit(pts), OutlineSpline.fit(with_duplicates)
    np.testing.assert_allclose(a.sample(50), b.sample(50), atol=1e-9)


def test_dict_round_trip_is_plain_json(circle_spline):
    data = json.loads(json.dumps(circle_spline.to_dict()))
    assert set(data) == {"knots", "coefficients", "degree", "t_range"}
    again = OutlineSpline.from_dict(data)
    t = np.linspace(*circle_spline.t_range, 77)
    np.testing.assert_array_equal(again.evaluate(t), circle_spline.evaluate(t))
    assert again.t_range == circle_spline.t_range
    with pytest.raises(OutlineError, match="knots"):
        OutlineSpline.from_dict({"degree": 3})


def test_validate_outline_errors():
    with pytest.raises(OutlineError, match="outline has 2 points; at least 4 are needed"):
        validate_outline([[0, 0], [1, 1]])
    with pytest.raises(OutlineError, match="outline crosses itself at point 0"):
        validate_outline([[0, 0], [10, 10], [10, 0], [0, 10]])  # bow-tie
    with pytest.raises(OutlineError, match="NaN"):
        validate_outline([[0, 0], [1, 0], [np.nan, 1], [0, 1]])
    with pytest.raises(OutlineError):
        OutlineSpline.fit([[0, 0], [10, 10], [10, 0], [0, 10]])
    validate_outline(circle(50))


def test_self_intersection_found_in_long_outlines():
    th = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    figure_eight = np.column_stack([200 * np.sin(th), 100 * np.sin(2 * th)])
    where = first_self_intersection(figure_eight)
    assert where is not None and abs(figure_eight[where, 0]) < 1.0  # crossing at the origin
    assert first_self_intersection(circle(2000)) is None
    spike = circle(20)
    spike = np.vstack([spike[:5], spike[3:4], spike[5:]])  # goes back along its own track
    assert first_self_intersection(spike) is not None


def test_resample_closed_polyline():
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], dtype=float)
    pts = resample_closed_polyline(square, n=8)
    np.testing.assert_allclose(pts, [[0, 0], [5, 0], [10, 0], [10, 5], [10, 10], [5, 10], [0, 10], [0, 5]])
    assert len(resample_closed_polyline(square, spacing=2.0)) == 20
    with pytest.raises(ValueError):
        resample_closed_polyline(square)
