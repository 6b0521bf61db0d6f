"""Quality's faster forms (issue 46) give the same answers as the straightforward ones:
whether a model outline point lies within the tolerance of an image edge, by a 3 x 3
look-up instead of the crop's whole distance transform."""
import cv2
import numpy as np
import pytest

from fluorogui.core.matching.quality import _near_edges
from fluorogui.core.outlines.edges import canny_edges


def implant_like_edges(seed: int) -> np.ndarray:
    """Canny edges of a noisy bright blob with a notch, like a crop around an implant."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:160, 0:200]
    blob = ((u - 95) / 70.0) ** 2 + ((v - 80) / 45.0) ** 2 < 1.0
    blob &= ~((np.abs(u - 100) < 8) & (v > 90))
    image = 0.3 + 0.4 * blob + rng.normal(0, 0.03, blob.shape)
    return canny_edges(cv2.GaussianBlur(image.astype(np.float32), (0, 0), 1.0), 0.04, 0.12, 1.0)


@pytest.mark.parametrize("tol_px", [1.5, 1.41, 1.99, 1.0, 2.5])
def test_near_edges_equal_the_distance_transform(tol_px):
    for seed in (0, 1):
        edges = implant_like_edges(seed)
        assert edges.any()
        rng = np.random.default_rng(seed)
        row = rng.integers(0, edges.shape[0], 4000)
        col = rng.integers(0, edges.shape[1], 4000)
        distance = cv2.distanceTransform((~edges).astype(np.uint8), cv2.DIST_L2, 5)
        expected = distance[row, col] <= tol_px
        assert 0 < expected.sum() < len(expected)
        np.testing.assert_array_equal(_near_edges(edges, row, col, tol_px), expected)
    none = np.zeros((30, 40), dtype=bool)  # no edges at all: nothing is near one
    assert not _near_edges(none, np.arange(30), np.arange(30), 1.5).any()


def test_outline_support_equals_the_balanced_tree_share():
    """The unbalanced k-d tree gives the same nearest distances, so the same share."""
    from scipy.spatial import cKDTree

    from fluorogui.core.matching.quality import outline_support
    from fluorogui.core.outlines.spline import resample_closed_polyline

    rng = np.random.default_rng(5)
    th = np.linspace(0, 2 * np.pi, 700, endpoint=False)
    r = 100 + 20 * np.sin(3 * th)
    model = np.column_stack([400 + 1.3 * r * np.cos(th), 380 + r * np.sin(th)])
    image = model[::2] + rng.normal(0, 1.0, (350, 2))  # within and beyond the tolerance
    dense = resample_closed_polyline(model, spacing=0.5)
    for tol_px in (0.5, 1.0, 1.5):
        expected = float(np.mean(cKDTree(dense).query(image)[0] <= tol_px))
        assert 0 < expected < 1 and outline_support(image, model, tol_px=tol_px) == expected
