"""The spline's faster forms (issue 46) give the same numbers, to the last bit, as the
straightforward computations they replace, on outlines like the real ones: a knee
implant's outline traced from pixels (about 700 points, some noise, either orientation)
and query points around it like projected model outlines."""
import numpy as np
import pytest

from fluorogui.core.outlines.spline import OutlineSpline, outward_normals


def traced_outline(seed: int, n: int = 700, clockwise: bool = True) -> np.ndarray:
    """A lumpy closed outline in pixels with sub-pixel noise, as the segmentation gives."""
    rng = np.random.default_rng(seed)
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 110 + 25 * np.sin(2 * th + 0.3) + 8 * np.cos(5 * th) + rng.normal(0, 0.15, n)
    pts = np.column_stack([512.3 + 1.4 * r * np.cos(th), 498.7 + r * np.sin(th)])
    return pts if clockwise else pts[::-1].copy()


def queries_around(spline: OutlineSpline, seed: int, n: int = 800) -> np.ndarray:
    """Points a few pixels off the outline, both sides, like a nearby pose's model outline."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(*spline.t_range, n)
    d1 = spline.derivative(t)
    normal = np.column_stack([d1[:, 1], -d1[:, 0]]) / np.linalg.norm(d1, axis=1)[:, None]
    return spline.evaluate(t) + rng.uniform(-6, 6, n)[:, None] * normal


def rolled_normals(p: np.ndarray) -> np.ndarray:
    tangent = np.roll(p, -1, axis=-2) - np.roll(p, 1, axis=-2)
    normal = np.stack([tangent[..., 1], -tangent[..., 0]], axis=-1)
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
    x, y = p[..., 0], p[..., 1]
    area2 = np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1)
    return np.where((area2 > 0)[..., None, None], normal, -normal)


@pytest.mark.parametrize("clockwise", [True, False])
def test_outward_normals_equal_the_rolled_form(clockwise):
    single = traced_outline(1, clockwise=clockwise)
    np.testing.assert_array_equal(outward_normals(single), rolled_normals(single))
    batch = np.stack([traced_outline(seed, n=180, clockwise=seed % 2 == 0) for seed in range(6)]).reshape(2, 3, 180, 2)
    np.testing.assert_array_equal(outward_normals(batch), rolled_normals(batch))
    for short in (single[:1], single[:2], single[:3]):  # the edge cases of the slices
        np.testing.assert_array_equal(outward_normals(short), rolled_normals(short))


def straightforward_evaluate(spline: OutlineSpline, t: np.ndarray) -> list[np.ndarray]:
    """g, g', g'' by fancy indexing of the (intervals, 4, 2) coefficients, as before."""
    t = spline.wrap(t)
    i = np.clip(np.searchsorted(spline._breaks, t, side="right") - 1, 0, spline._coeffs.shape[0] - 1)
    dx = (t - spline._breaks[i])[:, None]
    local = spline._coeffs[i]
    a, b, c = local[:, 0], local[:, 1], local[:, 2]
    ax = a * dx
    return [((ax + b) * dx + c) * dx + local[:, 3], (3.0 * ax + 2.0 * b) * dx + c, 6.0 * ax + 2.0 * b]


def straightforward_length(spline: OutlineSpline, spacing: float) -> tuple[int, float]:
    """Points and length of the polyline at <= ``spacing`` px, chord lengths by np.linalg.norm."""
    n = 64
    while True:
        t = spline.t_range[0] + np.arange(n + 1) * (spline.period / n)
        pts = spline.evaluate(t[:-1])
        seg = np.linalg.norm(np.diff(np.vstack([pts, pts[:1]]), axis=0), axis=1)
        if seg.max() <= spacing:
            return n, float(np.concatenate([[0.0], np.cumsum(seg)])[-1])
        n = int(np.ceil(n * seg.max() / spacing * 1.05))


def straightforward_closest(spline: OutlineSpline, p: np.ndarray):
    """``closest`` with fancy indexing, the chords' lengths computed per query and
    np.linalg.norm's lengths."""
    poly, tp, tree, chords, _ = spline._seed_tree()
    _, k = tree.query(p)
    before = (k - 1) % len(poly)
    t_before = tp[before] - np.where(k == 0, spline.period, 0.0)
    rel, along, back = p - poly[k], chords[k], -chords[before]
    w_after = np.clip(np.einsum("ij,ij->i", rel, along) / np.einsum("ij,ij->i", along, along), 0, 1)
    w_before = np.clip(np.einsum("ij,ij->i", rel, back) / np.einsum("ij,ij->i", back, back), 0, 1)
    miss_after, miss_before = rel - w_after[:, None] * along, rel - w_before[:, None] * back
    use_after = np.einsum("ij,ij->i", miss_after, miss_after) <= np.einsum("ij,ij->i", miss_before, miss_before)
    t = np.where(use_after, tp[k] + w_after * (tp[k + 1] - tp[k]), tp[k] - w_before * (tp[k] - t_before))
    t, g, d1 = spline._refine(p, t, t_before, tp[k + 1], steps=1)
    n = np.column_stack([d1[:, 1], -d1[:, 0]]) * spline.outward_sign()
    return np.linalg.norm(p - g, axis=1), g, n / np.linalg.norm(n, axis=1, keepdims=True), spline.wrap(t)


@pytest.mark.parametrize("seed", [2, 3])
def test_spline_evaluation_and_closest_equal_the_straightforward_forms(seed):
    spline = OutlineSpline.fit(traced_outline(seed, clockwise=seed % 2 == 0))
    t = np.random.default_rng(seed).uniform(spline.t_range[0] - 50, spline.t_range[1] + 50, 3000)
    for fast, plain in zip(spline._evaluate_all(t, 2), straightforward_evaluate(spline, t)):
        np.testing.assert_array_equal(fast, plain)
    n, length = straightforward_length(spline, spline.POLYLINE_SPACING_PX)
    assert len(spline._dense_polyline()[0]) == n and spline.length_px == length
    assert len(spline._seed_tree()[0]) == straightforward_length(spline, spline.SEED_SPACING_PX)[0]
    p = queries_around(spline, seed)
    for fast, plain in zip(spline.closest(p), straightforward_closest(spline, p)):
        np.testing.assert_array_equal(fast, plain)


def test_wrap_equals_the_modulo_form():
    spline = OutlineSpline.fit(traced_outline(4))
    t0, period = spline.t_range[0], spline.period
    rng = np.random.default_rng(4)
    inside = rng.uniform(*spline.t_range, 700)
    cases = [inside, np.r_[inside, t0 - 1e-9], np.r_[inside, spline.t_range[1]], np.r_[inside, -0.0, 0.0],
             rng.uniform(t0 - 3 * period, t0 + 3 * period, 700), np.zeros(0), np.float64(t0 + 1.5), -0.0]
    for t in cases:
        expected = t0 + np.mod(np.asarray(t, dtype=float) - t0, period)
        got = spline.wrap(t)
        assert np.shape(got) == np.shape(expected)
        np.testing.assert_array_equal(got, expected)
        assert np.array_equal(np.signbit(got), np.signbit(expected))


def test_row_lengths_equal_numpy_norm():
    """``_row_lengths`` (outline steps, chords, point-to-spline distances, the fold test's
    scale) gives np.linalg.norm's numbers, tiny, huge and zero rows included."""
    from fluorogui.core.outlines.spline import _row_lengths

    rng = np.random.default_rng(6)
    steps = np.diff(traced_outline(6), axis=0)
    odd = np.array([[0.0, 0.0], [-0.0, 0.0], [1e-200, 3e-201], [1e150, -2e150], [3.0, -4.0]])
    for v in (steps, rng.normal(0, 1, (5000, 2)) * 10.0 ** rng.uniform(-12, 12, (5000, 1)), odd):
        np.testing.assert_array_equal(_row_lengths(v), np.linalg.norm(v, axis=1))
