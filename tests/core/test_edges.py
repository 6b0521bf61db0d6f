"""Canny edge chains, sub-pixel edge localisation and outline selection (fluorogui.core.outlines.edges)."""
import cv2
import numpy as np
import pytest

from fluorogui.core.outlines.edges import (
    EdgeError,
    canny_edges,
    component_outline,
    edge_contours,
    outline_from_mask,
    select_outline,
    uncovered_arc,
)
from fluorogui.core.outlines.spline import OutlineSpline, validate_outline
from fluorogui.core.projection.geometry import View
from fluorogui.simulation.render import render_fluoro

VIEW = View.looking_at([0, 0, -1000], [0, 0, 0], [0, -1, 0], 1000.0, image_size=(256, 256),
                       pitch=0.25)  # z=0 at 0.25 mm/px


def flat_polygon(xy_mm):
    """Triangle fan of a polygon in the plane z = 0 and its exact outline in pixels."""
    n = len(xy_mm)
    vertices = np.vstack([np.column_stack([xy_mm, np.zeros(n)]), [[*xy_mm.mean(axis=0), 0.0]]])
    faces = np.array([[n, i, (i + 1) % n] for i in range(n)])
    return (vertices, faces), VIEW.project(vertices[:n])


def disc(radius_mm=15.0, centre=(0.3, -0.2)):
    th = np.linspace(0, 2 * np.pi, 1440, endpoint=False)
    return flat_polygon(np.asarray(centre) + radius_mm * np.column_stack([np.cos(th), np.sin(th)]))


def rotated_square(half_mm=14.0, angle_deg=30.0, centre=(0.2, 0.35)):
    a = np.radians(angle_deg)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float) * half_mm
    return flat_polygon(np.asarray(centre) + corners @ rot.T)


def signed_distance(points, polygon_px):
    """Distance of points to a polygon, positive outside."""
    contour = polygon_px.astype(np.float32).reshape(-1, 1, 2)
    return np.array([-cv2.pointPolygonTest(contour, (float(u), float(v)), True) for u, v in points])


@pytest.mark.parametrize("shape", ["disc", "square"])
def test_subpixel_edges_are_unbiased(shape):
    rng = np.random.default_rng(11)
    means, rms = [], []
    for angle in (0.0, 17.0, 30.0, 41.0):
        mesh, truth = disc(centre=rng.uniform(-0.5, 0.5, 2)) if shape == "disc" else rotated_square(angle_deg=angle)
        image = render_fluoro(VIEW, [mesh], rng)  # shaded background, blur 0.7 px, noise 0.02
        points = np.vstack(edge_contours(image, sigma=1.0))
        if shape == "square":  # corners are rounded by any blur: judge the straight sides
            points = points[np.min(np.linalg.norm(points[:, None] - truth[None], axis=2), axis=1) > 4.0]
        d = signed_distance(points, truth)
        assert np.abs(d).max() < 0.4  # measured 0.165-0.212 (disc), 0.127-0.200 px (square)
        means.append(d.mean())
        rms.append(np.sqrt(np.mean(d**2)))
    # seeded noise. Measured: means -0.025..-0.005 (disc, on average -0.015), -0.006..+0.003 px
    # (square); RMS 0.056-0.062 (disc), 0.036-0.075 px (square)
    assert abs(np.mean(means)) < 0.03 and max(abs(m) for m in means) < 0.05
    assert max(rms) < 0.145


def test_edge_contours_visit_each_pixel_once():
    mesh, _ = disc()
    image = render_fluoro(VIEW, [mesh], np.random.default_rng(0), noise_sd=0.0, background="flat")
    contours = edge_contours(image, subpixel=False)
    pixels = np.vstack(contours).astype(int)
    assert len(np.unique(pixels, axis=0)) == len(pixels)
    assert len(pixels) == canny_edges(image).sum()
    longest = max(contours, key=len)
    steps = np.abs(np.diff(longest, axis=0)).max(axis=1)
    assert steps.max() <= 1  # ordered: consecutive pixels are neighbours


def test_canny_thresholds_are_fractions():
    mesh, _ = disc()
    image = render_fluoro(VIEW, [mesh], np.random.default_rng(0))
    assert canny_edges(image, 0.1, 0.3).sum() > 300
    assert not canny_edges(image, 0.1, 0.3).all()
    with pytest.raises(ValueError):
        canny_edges(image, 0.5, 0.2)


def test_component_outline_of_a_disc():
    mesh, truth = disc()
    image = render_fluoro(VIEW, [mesh], np.random.default_rng(5))
    predicted = truth[::20] + np.array([4.0, -3.0])  # a rough prediction, a few pixels off
    outline = component_outline(image, predicted)
    validate_outline(outline)
    spline = OutlineSpline.fit(outline)
    d = signed_distance(spline.sample(400), truth)
    assert abs(d.mean()) < 0.035 and np.sqrt(np.mean(d**2)) < 0.1  # measured -0.017, 0.050 px
    assert abs(spline.length_px - 2 * np.pi * 60.0) < 1.0  # measured +0.57 px


def circle_px(radius, centre=(128.0, 128.0), n=400, start=0.0, stop=2 * np.pi):
    th = np.linspace(start, stop, n, endpoint=stop - start < 2 * np.pi - 1e-9)
    return np.asarray(centre) + radius * np.column_stack([np.cos(th), np.sin(th)])


def test_select_outline_picks_the_predicted_contour():
    rng = np.random.default_rng(2)
    target = circle_px(60.0) + rng.normal(0, 0.05, (400, 2))
    distractors = [
        circle_px(40.0),  # inner edge
        circle_px(60.0, centre=(160.0, 128.0)),  # same shape, elsewhere
        np.column_stack([np.linspace(0, 255, 300), np.full(300, 70.0)]),  # long straight edge
        circle_px(62.0, start=0.0, stop=1.0, n=30),  # short piece next to the target
    ]
    predicted = circle_px(58.0, centre=(130.0, 127.0), n=50)
    chosen = select_outline(distractors[:2] + [target] + distractors[2:], predicted)
    assert chosen is target


def test_select_outline_merges_pieces_in_order():
    truth = circle_px(60.0, n=1200)
    arcs = [truth[i:i + 250] for i in (0, 300, 600, 900)]  # four pieces with gaps
    shuffled = [arcs[2], arcs[0][::-1], arcs[3], arcs[1][::-1], circle_px(20.0)]
    merged = select_outline(shuffled, circle_px(58.0, n=80), merge=True)
    validate_outline(merged)
    spline = OutlineSpline.fit(merged)
    d, _, _, _ = spline.closest(truth)
    assert np.median(d) < 0.0014 and d.max() < 0.0045  # gaps bridged smoothly: measured 0.00069, 0.0023 px
    with pytest.raises(EdgeError):
        select_outline([circle_px(20.0)], circle_px(80.0), merge=True)


def test_outline_from_mask():
    mask = np.zeros((50, 60), dtype=bool)
    mask[10:20, 5:25] = True
    mask[30:32, 40:42] = True  # smaller region, ignored
    pts = outline_from_mask(mask)
    assert pts.min(axis=0).tolist() == [5, 10] and pts.max(axis=0).tolist() == [24, 19]
    edges = outline_from_mask(mask, offset_px=0.5)
    side = edges[(edges[:, 1] > 12) & (edges[:, 1] < 17)]
    assert set(np.round(side[:, 0], 6)) == {4.5, 24.5}
    with pytest.raises(EdgeError):
        outline_from_mask(np.zeros((5, 5), dtype=bool))


def half_weak_disc(weak_step=20.0, radius=60.0, centre=(128.0, 128.0), seed=3):
    """A dark disc (40) on a bright field (200) above its equator and on 'bone' (40 +
    ``weak_step``) below it: the lower half of its outline is a faint edge next to strong
    ones, like a tibial keel beside the tray."""
    v, u = np.mgrid[0:256, 0:256].astype(float)
    r = np.hypot(u - centre[0], v - centre[1])
    inside = np.clip(radius + 0.5 - r, 0.0, 1.0)  # one-pixel linear ramp
    below = np.clip(v - centre[1] + 0.5, 0.0, 1.0)
    surround = 200.0 * (1.0 - below) + (40.0 + weak_step) * below
    image = inside * 40.0 + (1.0 - inside) * surround
    image = cv2.GaussianBlur(image, (0, 0), 1.0) + np.random.default_rng(seed).normal(0, 0.5, image.shape)
    return np.clip(image, 0, 255).astype(np.float32), circle_px(radius, centre=centre, n=720)


def test_component_outline_fills_faint_gaps_with_weak_edges():
    image, truth = half_weak_disc()
    lower = truth[truth[:, 1] > 140]
    assert not canny_edges(image)[np.round(lower[:, 1]).astype(int), np.round(lower[:, 0]).astype(int)].any()
    predicted = truth[::12] + np.array([2.0, -1.5])
    # without the weak edges the outline bridges the lower half with a chord
    chord = OutlineSpline.fit(component_outline(image, predicted, gap_fill=None))
    assert chord.closest(lower)[0].max() > 30.0
    # with them (the default) it follows the faint edge
    spline = OutlineSpline.fit(component_outline(image, predicted))
    d = spline.closest(truth)[0]
    assert np.sqrt(np.mean(d**2)) < 0.3 and d.max() < 2.0  # measured 0.150, 1.46 px
    assert abs(spline.length_px - 2 * np.pi * 60.0) < 3.0  # measured +2.36 px


def test_gap_fill_leaves_a_fully_covered_outline_unchanged():
    mesh, truth = disc()
    image = render_fluoro(VIEW, [mesh], np.random.default_rng(5))
    predicted = truth[::20] + np.array([4.0, -3.0])
    np.testing.assert_array_equal(component_outline(image, predicted),
                                  component_outline(image, predicted, gap_fill=None))


def test_uncovered_arc_finds_runs_longer_than_the_minimum():
    predicted = circle_px(50.0, n=400)
    on = circle_px(50.0, n=2000)
    th = np.arctan2(on[:, 1] - 128.0, on[:, 0] - 128.0)
    keep = ~((th > 0.0) & (th < 0.5)) & ~((th > 2.0) & (th < 2.05))  # a 25 px and a 2.5 px gap
    _, gap = uncovered_arc(on[keep], predicted, min_gap_px=6.0)
    length = 2 * np.pi * 50.0
    assert abs(gap.sum() * length / len(gap) - 25.0) < 2.1  # measured 23.9 px
    _, none = uncovered_arc(on, predicted)
    assert not none.any()
    _, everything = uncovered_arc(np.zeros((0, 2)), predicted)
    assert everything.all()


def test_subpixel_edges_takes_more_points_than_remap_allows_in_a_row():
    rng = np.random.default_rng(0)
    image = cv2.GaussianBlur(rng.normal(100, 20, (300, 300)).astype(np.float32), (0, 0), 2.0)
    from fluorogui.core.outlines.edges import smoothed_gradients, subpixel_edges
    _, gx, gy = smoothed_gradients(image)
    v, u = np.mgrid[0:300, 0:300]
    pixels = np.column_stack([u.ravel(), v.ravel()]).astype(float)  # 90 000 > 32 767
    refined, grad = subpixel_edges(gx, gy, pixels)
    assert refined.shape == pixels.shape and np.all(np.abs(refined - pixels) <= 1.0 + 1e-9)
    part, _ = subpixel_edges(gx, gy, pixels[:1000])
    np.testing.assert_allclose(refined[:1000], part)
