"""The segmentation's shortcuts give what the plain computation gives, bit for bit.

Each is held to the straightforward version it replaced, written out here, so a speed-up in
finding a component's outline cannot move a matched pose."""
import cv2
import numpy as np
import pytest

from fluorogui.core.outlines.edges import best_translation, canny_edges, gradient_magnitude, smoothed_gradients
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
