"""The segmentation's shortcuts give what the plain computation gives, bit for bit.

Each is held to the straightforward version it replaced, written out here, so a speed-up in
finding a component's outline cannot move a matched pose."""
import cv2
import numpy as np
import pytest

from fluorogui.core.outlines.edges import (
    _Along,
    _band,
    _dark_edge_points,
    _EdgeMap,
    _runs,
    best_translation,
    canny_edges,
    gradient_magnitude,
    smoothed_gradients,
    subpixel_edges,
    uncovered_arc,
)
from fluorogui.core.outlines.quantile import tail_percentile
from fluorogui.core.outlines.spline import resample_closed_polyline


def _arrays(rng, count):
    """Arrays of the kinds percentiles are taken of: float32 and float64, smooth and heavy
    tailed, with many ties, contiguous or strided crops."""
    for i in range(count):
        n = int(rng.integers(600, 6000)) * 8
        kind = i % 4
        if kind == 0:
            x = rng.normal(size=n)
        elif kind == 1:
            x = rng.exponential(size=n).astype(np.float32)
        elif kind == 2:
            x = rng.integers(0, 50, n).astype(np.float32)  # ties everywhere
        else:
            x = np.round(rng.normal(size=n), 2)
        yield x.reshape(-1, 8)[:, 1:6] if i % 3 == 0 else x


def test_tail_percentile_is_numpys_percentile():
    rng = np.random.default_rng(46)
    for x in _arrays(rng, 240):
        for q in (99.9, 0.5, 99.0, 5.0, 50.0, float(rng.uniform(0, 100)), 100.0, 0.0):
            assert tail_percentile(x, q) == float(np.percentile(x, q)), (x.dtype, x.size, q)


def test_tail_percentile_falls_back_where_it_must():
    x = np.random.default_rng(1).normal(size=20000).astype(np.float32)
    x[123] = np.nan
    assert np.isnan(tail_percentile(x, 99.9)) and np.isnan(tail_percentile(x, 0.5))
    small = np.arange(10.0)
    assert tail_percentile(small, 99.9) == float(np.percentile(small, 99.9))
    ints = np.arange(10000)
    assert tail_percentile(ints, 99.9) == float(np.percentile(ints, 99.9))


def _plain_canny(image, low, high, roi=None):
    """``canny_edges`` as it was written before: np.percentile, np.clip of np.round."""
    _, gx, gy = smoothed_gradients(image, 1.0)
    mag = np.hypot(gx, gy)
    region = mag
    if roi is not None:
        u0, v0, u1, v1 = roi
        region = mag[v0:v1, u0:u1]
    reference = float(np.percentile(region, 99.9)) or float(mag.max())
    scale = 8000.0 / reference
    dx = np.clip(np.round(gx * scale), -32767, 32767).astype(np.int16)
    dy = np.clip(np.round(gy * scale), -32767, 32767).astype(np.int16)
    return cv2.Canny(dx, dy, low * 8000.0, high * 8000.0, L2gradient=True) > 0


@pytest.mark.parametrize("roi", [None, (30, 20, 200, 180)])
def test_canny_edges_are_the_plain_computation(roi):
    rng = np.random.default_rng(7)
    for _ in range(6):
        image = cv2.GaussianBlur(rng.uniform(0, 1, (240, 260)).astype(np.float32), (0, 0), 3.0)
        image[60:150, 80:200] *= 0.4  # a dark block: strong edges, some beyond the reference
        for low, high in ((0.1, 0.3), (0.04, 0.12)):
            assert np.array_equal(canny_edges(image, low, high, roi=roi), _plain_canny(image, low, high, roi))


def _plain_best_translation(edge_mask, pts, search_px):
    """The chamfer search as it was written before: every shift's points rounded anew."""
    distance = np.minimum(cv2.distanceTransform((~edge_mask).astype(np.uint8), cv2.DIST_L2, 5), 20.0)
    height, width = distance.shape

    def costs(shifts):
        u = np.minimum(np.maximum(np.round(pts[None, :, 0] + shifts[:, None, 0]).astype(int), 0), width - 1)
        v = np.minimum(np.maximum(np.round(pts[None, :, 1] + shifts[:, None, 1]).astype(int), 0), height - 1)
        return distance[v, u].mean(axis=1)

    best = np.zeros(2)
    for step, reach in ((8, search_px), (2, 8), (1, 2)):
        offsets = np.arange(-reach, reach + 1, step)
        grid = best + np.array([(du, dv) for du in offsets for dv in offsets], dtype=float)
        best = grid[int(np.argmin(costs(grid)))]
    return best


def test_best_translation_is_the_plain_search():
    rng = np.random.default_rng(11)
    for i in range(25):
        edges = np.zeros((220, 240), np.uint8)
        centre = rng.uniform(70, 160, 2)
        axes = rng.uniform(25, 50, 2)
        cv2.ellipse(edges, (int(centre[0]), int(centre[1])), (int(axes[0]), int(axes[1])), float(rng.uniform(0, 180)),
                    0, 360, 1)
        edges[rng.integers(0, 220, 300), rng.integers(0, 240, 300)] = 1  # clutter
        th = np.linspace(0, 2 * np.pi, int(rng.integers(40, 400)), endpoint=False)
        pred = centre + rng.normal(0, 6, 2) + np.column_stack([axes[0] * np.cos(th), axes[1] * np.sin(th)])
        if i % 5 == 0:
            pred = np.round(pred * 2) / 2  # half-pixel points: rounding ties
        search = int(rng.choice([8, 30, 60]))
        pts = resample_closed_polyline(pred, n=min(300, max(8, len(pred))))
        plain = _plain_best_translation(edges > 0, pts, search)
        assert np.array_equal(best_translation(edges > 0, pred, search), plain)


def test_gradients_are_sobel_divided_by_eight_and_their_hypot():
    rng = np.random.default_rng(5)
    image = cv2.GaussianBlur(rng.uniform(0, 1, (300, 280)).astype(np.float32), (0, 0), 2.0)
    image[100:200, 50:150] *= 0.3
    img, gx, gy = smoothed_gradients(image, 1.0)
    assert np.array_equal(gx, cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT) / 8.0)
    assert np.array_equal(gy, cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT) / 8.0)
    assert np.array_equal(gradient_magnitude(gx, gy), np.hypot(gx, gy))
    for _ in range(5):  # magnitudes from 1e-6 to 1e2, either much larger than the other
        x, y = (rng.normal(size=400_000) * 10.0 ** rng.uniform(-6, 2, 400_000) for _ in range(2))
        x, y = x.astype(np.float32), y.astype(np.float32)
        assert np.array_equal(gradient_magnitude(x, y), np.hypot(x, y))


def _component_scene(rng, size=(260, 300)):
    """A blurred dark rounded component on a noisy brighter surround, its Canny edges, and
    a prediction of its outline a few pixels off (as the matcher's start pose gives it)."""
    image = np.full(size, 0.7, np.float32)
    centre = rng.uniform(110, 150, 2)
    axes = rng.uniform(45, 80, 2)
    cv2.ellipse(image, (int(centre[0]), int(centre[1])), (int(axes[0]), int(axes[1])), float(rng.uniform(0, 180)), 0,
                360, 0.25, -1)
    image = cv2.GaussianBlur(image, (0, 0), 1.5) + rng.normal(0, 0.02, size).astype(np.float32)
    th = np.linspace(0, 2 * np.pi, int(rng.integers(200, 700)), endpoint=False)
    pred = centre + rng.normal(0, 3, 2) + np.column_stack([(axes[0] + 2) * np.cos(th), (axes[1] - 2) * np.sin(th)])
    return image, canny_edges(image, 0.04, 0.12), pred


def _plain_subpixel_maps(pixels, direction, step, rows, width):
    k = len(pixels)
    map_u = np.pad((pixels[:, 0] + step * direction[:, 0]).astype(np.float32), (0, rows * width - k))
    map_v = np.pad((pixels[:, 1] + step * direction[:, 1]).astype(np.float32), (0, rows * width - k))
    return map_u.reshape(rows, width), map_v.reshape(rows, width)


def test_subpixel_edges_are_the_plain_computation():
    """The sample maps filled in place are np.pad's; more than 4096 pixels (several rows of
    samples, the last padded) included."""
    rng = np.random.default_rng(3)
    image = cv2.GaussianBlur(rng.uniform(0, 1, (400, 420)).astype(np.float32), (0, 0), 1.2)
    _, gx, gy = smoothed_gradients(image, 1.0)
    mag = gradient_magnitude(gx, gy)
    for count in (1, 7, 4096, 5000, 9001):
        pixels = np.column_stack([rng.integers(0, 420, count), rng.integers(0, 400, count)]).astype(float)
        grad = np.column_stack([gx[pixels[:, 1].astype(int), pixels[:, 0].astype(int)],
                                gy[pixels[:, 1].astype(int), pixels[:, 0].astype(int)]]).astype(float)
        direction = grad / np.maximum(np.linalg.norm(grad, axis=1, keepdims=True), 1e-12)
        width = min(count, 4096)
        rows = -(-count // width)
        samples = [cv2.remap(mag, *_plain_subpixel_maps(pixels, direction, step, rows, width), cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_REFLECT).reshape(-1)[:count].astype(float)
                   for step in (-1.0, 0.0, 1.0)]
        before, centre, after = (np.log(np.maximum(x, 1e-12)) for x in samples)
        curvature = before - 2.0 * centre + after
        peaked = curvature < -1e-12
        offset = np.clip(np.where(peaked, 0.5 * (before - after) / np.where(peaked, curvature, -1.0), 0.0), -1, 1)
        refined, got_grad = subpixel_edges(gx, gy, pixels, magnitude=mag)
        assert np.array_equal(refined, pixels + offset[:, None] * direction)
        assert np.array_equal(got_grad, grad)


def _plain_uncovered_arc(points, predicted, tolerance_px, min_gap_px, hidden):
    """``uncovered_arc`` as it was written before: the bins' pixels found at every call, a
    Python loop over the runs of uncovered bins."""
    along = _Along(predicted)
    dense, arc, total = along.dense, along.arc, along.total
    n_bins = max(4, int(np.ceil(total / 1.0)))
    covered = np.zeros(n_bins, dtype=bool)
    if hidden is not None:
        centre = np.interp((np.arange(n_bins) + 0.5) * total / n_bins, arc, np.arange(len(dense)))
        at = dense[np.clip(np.round(centre).astype(int), 0, len(dense) - 1)]
        col = np.clip(np.round(at[:, 0]).astype(int), 0, hidden.shape[1] - 1)
        row = np.clip(np.round(at[:, 1]).astype(int), 0, hidden.shape[0] - 1)
        covered |= hidden[row, col]
    dist, nearest = along.query(points)
    bins = np.minimum((arc[nearest] / total * n_bins).astype(int), n_bins - 1)
    covered[bins[dist <= tolerance_px]] = True
    gap = ~covered
    if gap.all() or not gap.any():
        return bins, gap
    shift = int(np.flatnonzero(covered)[0])
    keep = np.zeros(n_bins, dtype=bool)
    for start, stop in _runs(np.roll(gap, -shift)):
        if (stop - start) * total / n_bins >= min_gap_px:
            keep[start:stop] = True
    return bins, np.roll(keep, shift)


def test_uncovered_arc_is_the_plain_computation():
    rng = np.random.default_rng(17)
    for i in range(30):
        image, edges, pred = _component_scene(rng)
        rows, cols = np.nonzero(edges)
        points = np.column_stack([cols, rows]).astype(float) + rng.uniform(-0.5, 0.5, (len(rows), 2))
        points = points[rng.uniform(size=len(points)) < rng.uniform(0.2, 1.0)]  # gaps of every length
        hidden = None
        if i % 2:
            hidden = np.zeros(edges.shape, bool)
            hidden[:, : int(rng.integers(60, 200))] = True
        along = _Along(pred)
        for min_gap in (6.0, 0.0, 2.5, 40.0):
            for tolerance in (8.0, 1.0):
                plain = _plain_uncovered_arc(points, pred, tolerance, min_gap, hidden)
                got = uncovered_arc(points, pred, tolerance_px=tolerance, min_gap_px=min_gap, hidden=hidden,
                                    along=along, near=along.query(points))
                assert all(np.array_equal(a, b) for a, b in zip(got, plain)), (i, min_gap, tolerance)


def test_dark_edge_points_of_an_edge_map_are_the_plain_computation():
    """Pixels taken from the map's pixel list and a given band, labels made once per map:
    the points, labels and polarity of ``nonzero(edges & band)`` with fresh labels."""
    rng = np.random.default_rng(23)
    for _ in range(12):
        image, edges, pred = _component_scene(rng)
        gradients = smoothed_gradients(image, 1.0)
        magnitude = gradient_magnitude(gradients[1], gradients[2])
        edge_map = _EdgeMap(edges)
        for shift in ((0.0, 0.0), (3.0, -2.0)):  # two predictions measured against the same map
            shifted = pred + shift
            along = _Along(shifted)
            rows, cols = np.nonzero(edges & _band(edges.shape, shifted, 8.0))
            labels = cv2.connectedComponents(edges.astype(np.uint8), connectivity=8)[1]
            refined, grad = subpixel_edges(gradients[1], gradients[2], np.column_stack([cols, rows]).astype(float),
                                           magnitude=magnitude)
            near = along.query(refined)
            agrees = np.einsum("ij,ij->i", grad, along.normals[near[1]]) > 0.5 * np.linalg.norm(grad, axis=1)
            got = _dark_edge_points(image, edge_map, shifted, 1.0, polarity="dark", gradients=gradients, within_px=8.0,
                                    along=along, magnitude=magnitude, band=_band(edges.shape, shifted, 8.0))
            for a, b in zip(got, (refined, labels[rows, cols], agrees, near)):
                a, b = (a, b) if isinstance(a, np.ndarray) else (np.asarray(a), np.asarray(b))
                assert np.array_equal(a, b)
