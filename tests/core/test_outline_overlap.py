"""Find's overlap check leaves out what the image outline closed by a chord across a gap
(no edge traced there), but only where the silhouette lies on image edges."""
import cv2
import numpy as np

from fluorogui.core.outlines.spline import OutlineSpline
from fluorogui.core.search.outline_overlap import untraced


def _square(side: float = 160.0, at: float = 40.0, step: float = 1.0) -> np.ndarray:
    """A square outline, clockwise on screen, points ``step`` px apart (full resolution)."""
    s = np.arange(0.0, side, step)
    top = np.c_[at + s, np.full_like(s, at)]
    right = np.c_[np.full_like(s, at + side), at + s]
    bottom = np.c_[at + side - s, np.full_like(s, at + side)]
    left = np.c_[np.full_like(s, at), at + side - s]
    return np.vstack([top, right, bottom, left])


def _fill(points: np.ndarray, shape) -> np.ndarray:
    out = np.zeros(shape, np.uint8)
    cv2.fillPoly(out, [np.round((points * 0.5 - 0.25) * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    return out > 0


def _case(edges_at_corner: bool):
    silhouette = _square()
    # the traced outline misses the bottom-right corner: 60 px either side of it untraced,
    # so the spline closes it with a chord across the gap
    corner = np.array([200.0, 200.0])
    traced = silhouette[np.abs(silhouette - corner).sum(1) > 60.0]
    spline = OutlineSpline.fit(traced)
    assert len(spline.gaps) == 1
    image = np.full((256, 256), 0.8, np.float32)
    cv2.fillPoly(image, [np.round(silhouette if edges_at_corner else traced).astype(np.int32)], 0.3)
    shape = (128, 128)
    a, b = _fill(silhouette, shape), _fill(spline.sample(int(spline.length_px)), shape)
    return a, b, untraced(a, b, np.ones(shape, bool), spline, silhouette, image)


def test_a_chord_across_a_missed_edge_is_left_out():
    a, b, left_out = _case(edges_at_corner=True)
    corner = a & ~b  # what the chord cut off
    assert corner.sum() > 200  # measured 250 px (half resolution)
    assert left_out[corner].mean() > 0.95 and not left_out[a & b].any()
    # the IoU the verdict sees: 1 without the corner (0.96 with it)
    free = ~left_out
    assert np.count_nonzero(a & b & free) == np.count_nonzero((a | b) & free)


def test_a_silhouette_off_the_edges_keeps_its_region():
    # the image has no corner there (the outline is right, the silhouette is not)
    _, _, left_out = _case(edges_at_corner=False)
    assert not left_out.any()
