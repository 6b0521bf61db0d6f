"""A bone's edge beside the rim (core.outlines.second_edge): found where it is, and modelled by the
rim fit so that it no longer pulls the outline. The bone is drawn here by hand (a
cylinder's chord, exp(-k sqrt(x)), blurred), not by the code under test."""
import cv2
import numpy as np
import pytest
from scipy.ndimage import gaussian_filter
from scipy.spatial import cKDTree
from test_rim import VIEWS, signed_distance_to_truth

from fluorogui.core.matching.loop import predicted_outline
from fluorogui.core.outlines import rim
from fluorogui.core.outlines.edges import component_outline
from fluorogui.core.outlines.second_edge import second_edges
from fluorogui.reference.xray import Body, XrayModel, xray_image


def _straight_rim(k: float, edge_px: float, with_bone: bool = True):
    """A vertical metal edge at u = 99.5 (dark to the left) and, when ``with_bone``, a
    bone whose edge lies ``edge_px`` to its right and which covers the metal too."""
    u = np.arange(200)[None, :] - 99.5
    sharp = np.where(u < 0, 0.3, 1.0) * (np.exp(-k * np.sqrt(np.clip(edge_px - u, 0, None))) if with_bone else 1.0)
    image = gaussian_filter(np.repeat(sharp, 200, axis=0), 0.8)
    points = np.column_stack([np.full(101, 99.5), np.arange(50, 151)]).astype(float)
    return image, points, np.tile([1.0, 0.0], (101, 1))


@pytest.mark.parametrize("k, edge_px", [(0.35, 4.0), (0.15, 4.0), (0.5, 5.5), (0.35, 7.0)])
def test_a_bone_edge_beside_a_straight_rim_is_found(k, edge_px):
    found, darkness = second_edges(*_straight_rim(k, edge_px))
    # measured: 4.1 / 4.05 / 5.4 / 7.0 px, k 0.37 / 0.15 / 0.57 / 0.33
    assert np.isfinite(found).all()
    assert np.median(found) == pytest.approx(edge_px, abs=0.15)
    assert np.median(darkness) == pytest.approx(k, rel=0.15)


def test_no_edge_is_found_beside_a_bare_rim():
    found, _ = second_edges(*_straight_rim(0.35, 4.0, with_bone=False))
    assert np.isnan(found).all()


def _bone_band(image, outline, stretch, edge_px=4.0, k=0.35, reach_px=14.0):
    """``image`` (unblurred, noise-free) darkened by a bone whose edge runs ``edge_px``
    outside ``outline[stretch]`` (signed distance to the outline polygon) and which
    covers the metal inside it; then blurred (0.8 px) and given quantum noise, so that
    the metal and the bone are blurred together as on a detector."""
    h, w = image.shape
    rows, cols = np.mgrid[0:h, 0:w]
    pixels = np.column_stack([cols.ravel(), rows.ravel()]).astype(float)
    gap, _ = cKDTree(outline[stretch]).query(pixels)
    near = np.flatnonzero(gap <= reach_px)
    polygon = outline.astype(np.float32).reshape(-1, 1, 2)
    outside = np.array([-cv2.pointPolygonTest(polygon, (float(u), float(v)), True) for u, v in pixels[near]])
    factor = np.ones(len(pixels))
    factor[near] = np.exp(-k * np.sqrt(np.clip(edge_px - outside, 0, None)))
    blurred = gaussian_filter(image * factor.reshape(h, w), 0.8)
    return (np.random.default_rng(6).poisson(blurred * 3000.0) / 3000.0).astype(np.float32)


@pytest.mark.slow
@pytest.mark.parametrize("where", [0.0, 2 / 3])
def test_a_bone_edge_beside_a_stretch_no_longer_pulls_it(tray, monkeypatch, where):
    mesh, pose, world = tray
    view = VIEWS[0]
    sharp = xray_image(view, [Body(world, mesh.faces, 1.0)], XrayModel(photons=None, focal_spot_mm=0.0,
                                                                        detector_blur_px=0.0))
    canny = component_outline(gaussian_filter(sharp, 0.8), predicted_outline(mesh, pose, view))
    stretch = np.arange(int(len(canny) * where), int(len(canny) * where) + 40)
    spoiled = _bone_band(sharp, canny, stretch)

    def stretch_error(outline):
        near = cKDTree(canny[stretch[8:-8]]).query(outline)[0] < 1.0
        return signed_distance_to_truth(view, world, mesh.faces, outline[near]).mean()

    modelled, _ = rim.refine_outline(spoiled, view, mesh, pose, outline_px=canny)
    monkeypatch.setattr(rim, "second_edges", lambda image, points, *a: (np.full(len(points), np.nan),) * 2)
    monkeypatch.setattr(rim, "_GATHERED", [])  # gathered again, without the second edges
    ignored, _ = rim.refine_outline(spoiled, view, mesh, pose, outline_px=canny)
    print(f"stretch at {where:.2f}: modelled {stretch_error(modelled):+.3f} px, "
          f"ignored {stretch_error(ignored):+.3f} px")
    # measured: modelled -0.008 / -0.016 px, ignored -0.191 / -0.262 px; without the blur's
    # cross term of the bone and the shadow (sigma^2 [(B + G s) bone]' dt/dx) modelled
    # -0.048 / -0.056. (Until the bone was blurred here together with the metal, as a
    # detector does, the test's image had no such cross term and the model over-corrected.)
    assert stretch_error(ignored) < -0.15
    assert abs(stretch_error(modelled)) < 0.025
