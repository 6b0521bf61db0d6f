"""The rim's 1-D profile fit (core.outlines.rim) against profiles made here by direct convolution,
and the outline geometry it uses (core.outlines.profile_fit): a sloped background must not move
the edge, and the outline's curvature must be that of a circle."""
import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from fluorogui.core.outlines import rim
from fluorogui.core.outlines.profile_fit import outline_curvature
from fluorogui.core.outlines.spline import outward_normals


@pytest.mark.parametrize("slope", [-0.05, 0.0, 0.05])
def test_a_sloped_background_does_not_move_the_edge(slope):
    """A straight rim whose metal thickens like sqrt(depth), on a background that changes
    5 % per px across it, blurred by a Gaussian: the fit puts the boundary where it is.
    Without the blur's slope term (G sigma^2 dt/dx) it was 0.04 px off, inwards where the
    background brightens outwards (measured -0.042 / +0.039 px)."""
    sigma, mu, c = 0.9, 1.0, 2.0  # blur (px), attenuation (1/mm), path length c sqrt(px) (mm)
    fine = np.arange(-30.0, 30.0, 0.01)  # px, + outwards, the boundary at 0
    shadow = np.exp(-mu * c * np.sqrt(np.clip(-fine, 0.0, None)))
    image = gaussian_filter1d((1.0 + slope * fine) * shadow, sigma / 0.01)
    n = 20
    at = np.linspace(-0.5, 0.5, n, endpoint=False)  # the outline points, off the boundary
    s = at[:, None] + np.arange(-4.0, 5.0)[None, :]  # their pixels along the normal
    pts = rim._Points(s, np.interp(s, fine, image), np.ones_like(s), np.tile(c * np.sqrt(rim._L_OFFSETS), (n, 1)),
                      at, np.zeros_like(s), np.full(n, np.nan), np.zeros(n), np.zeros(n))
    boundary, _ = rim._best_positions(*rim._residuals(pts, mu, sigma))
    assert np.abs(boundary).max() < 0.0018  # measured 0.00064 / 0.00076 / 0.00089 px


@pytest.mark.parametrize("clockwise", [False, True])
def test_the_curvature_of_a_circle_is_one_over_its_radius(clockwise):
    radius = 12.0
    angle = np.arange(0.0, 2 * np.pi, 0.5 / radius)  # 0.5 px apart, as the rim's model outline
    circle = radius * np.column_stack([np.cos(angle), np.sin(angle)]) + [100.0, 80.0]
    circle = circle[::-1] if clockwise else circle
    bend = outline_curvature(circle, outward_normals(circle))
    assert bend == pytest.approx(np.full(len(circle), 1.0 / radius), rel=0.0027)  # measured 0.0014
    # a dent bends the other way
    dented = circle.copy()
    dented[:, 0] = np.where(dented[:, 0] > 100 + 0.8 * radius, 2 * (100 + 0.8 * radius) - dented[:, 0], dented[:, 0])
    assert outline_curvature(dented, outward_normals(dented)).min() < -0.5 / radius
