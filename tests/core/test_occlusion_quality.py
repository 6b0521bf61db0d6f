"""Occlusion-aware segmentation and matching, outline repair and the quality checks, on
rendered images (the scanline rasteriser of simulation.render, not the matcher's silhouette)."""
import cv2
import numpy as np
import pytest

from fluorogui.core.matching.loop import SegmentationError, predicted_outline, segment_and_match
from fluorogui.core.matching.problem import visible_points
from fluorogui.core.matching.quality import Quality, QualityThresholds, assess, judge
from fluorogui.core.outlines.spline import first_self_intersection, untangle_outline
from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import motion_between, pose_error, transform_points
from fluorogui.core.status import Status
from fluorogui.simulation.phantoms import femoral_component_mesh
from fluorogui.simulation.protocols import dual_orthogonal_views
from fluorogui.simulation.render import render_fluoro

TRUTH = np.array([2.0, 3.0, -4.0, 10.0, 20.0, -30.0])


def _block(centre, half):
    """A closed box mesh (the 'other component') centred at ``centre`` with half sizes ``half``."""
    c, h = np.asarray(centre, float), np.asarray(half, float)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * h + c
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return corners, faces


@pytest.fixture(scope="module")
def scene():
    mesh = prepare_mesh(*femoral_component_mesh())
    views = dual_orthogonal_views()
    world = transform_points(TRUTH, mesh.vertices)
    # a block overlapping the lower part of the component in both views
    centre = world.mean(0) + np.array([0.0, 0.0, -22.0])
    block = _block(centre, (20.0, 20.0, 9.0))
    rng = np.random.default_rng(3)
    images = [render_fluoro(v, [(world, mesh.faces), block], rng) for v in views]
    masks = []
    for v in views:
        mask = np.zeros((v.image_size[1], v.image_size[0]), np.uint8)
        hull = cv2.convexHull(np.round(v.project(block[0])).astype(np.int32))
        cv2.fillConvexPoly(mask, hull, 1)
        masks.append(cv2.dilate(mask, np.ones((7, 7), np.uint8)) > 0)
    return mesh, views, images, masks


@pytest.mark.slow
def test_occluded_outline_is_ignored_and_matters(scene):
    mesh, views, images, masks = scene
    overlap = [visible_points(m, predicted_outline(mesh, TRUTH, v)) for m, v in zip(masks, views)]
    assert all(0.05 < 1 - o.mean() < 0.6 for o in overlap)  # the block hides part of the outline in each view
    start = TRUTH + np.array([1.5, -1.0, 1.0, 2.0, -1.5, 1.0])
    aware = segment_and_match(images, views, mesh, start, occluded=masks)
    naive = segment_and_match(images, views, mesh, start)
    e_aware, e_naive = pose_error(aware.pose, TRUTH), pose_error(naive.pose, TRUTH)
    assert aware.converged
    # measured 0.0011 mm / 0.0047 deg
    assert np.abs(e_aware[:3]).max() < 0.0022 and np.abs(e_aware[3:]).max() < 0.0095, e_aware
    # the block's edges pull the unaware match away from the truth (measured 0.091 mm, 0.163 deg)
    assert np.abs(e_naive[:3]).max() > 0.05 and np.abs(e_naive[3:]).max() > 0.1, e_naive


@pytest.mark.slow
def test_quality_passes_the_right_pose_and_flags_a_wrong_one(scene):
    mesh, views, images, masks = scene
    right = segment_and_match(images, views, mesh, TRUTH + 0.5, occluded=masks)
    q = assess(images, views, mesh, right.pose, converged=right.converged, per_view_mean_mm=right.per_view_mean_mm,
               image_outlines=right.image_outlines, predicted=TRUTH + 0.5, occluded=masks)
    assert min(q.edge_support) == 1.0 and min(q.outline_support) == 1.0, q  # measured: every point
    assert judge(q) == (Status.MATCHED, "")
    wrong = TRUTH + np.array([0.0, 0.0, 0.0, 12.0, 0.0, 0.0])  # a pose turned 12 degrees off
    q_wrong = assess(images, views, mesh, wrong, converged=True, per_view_mean_mm=[0.15, 0.15], image_outlines=None,
                     predicted=TRUTH, occluded=masks)
    assert max(q_wrong.edge_support) < 0.5, q_wrong  # measured 0.42
    status, reason = judge(q_wrong)
    assert status == Status.NEEDS_REVIEW and "image edges" in reason and "predicted pose" not in reason


def test_judge_names_every_failed_check():
    q = Quality(False, [0.9, 0.12], [0.97, 0.6], [0.95, 0.95], jump_mm=30.0, jump_deg=3.0)
    status, reason = judge(q, QualityThresholds(), typical_view_mm=0.12)
    assert status == Status.NEEDS_REVIEW
    for piece in ("did not converge", "0.90 mm in view 1", "60 % of the model outline", "30.0 mm"):
        assert piece in reason
    assert "view 2 (" not in reason  # view 2's residual 0.12 is typical
    # the typical residual sets the limit between the floor and the ceiling
    q_ok = Quality(True, [0.29, 0.2], [0.99, 0.99], [0.99, 0.99])
    assert judge(q_ok, typical_view_mm=0.12)[0] == Status.MATCHED  # limit 0.30
    assert judge(q_ok, typical_view_mm=0.05)[0] == Status.NEEDS_REVIEW  # limit 0.25 (floor)


def test_segmentation_error_names_the_view(scene):
    mesh, views, images, _ = scene
    blank = [images[0], np.full_like(images[1], 0.8)]
    with pytest.raises(SegmentationError) as err:
        segment_and_match(blank, views, mesh, TRUTH)
    assert err.value.view == 1 and str(err.value).startswith("view 2: ")


def test_untangle_outline_cuts_small_loops_and_spikes():
    th = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    circle = 50 + 20 * np.column_stack([np.cos(th), np.sin(th)])
    looped = np.insert(circle, 10, [circle[12] + [3, 0], circle[8] + [3, 0]], axis=0)  # a bow-tie kink
    assert first_self_intersection(looped) is not None
    fixed = untangle_outline(looped)
    assert first_self_intersection(fixed) is None
    assert len(fixed) >= len(circle) - 4
    spiked = np.insert(circle, 5, [circle[5] + [0.0, 0.0] + (circle[5] - 50) * 0.3, circle[5]], axis=0)
    assert first_self_intersection(untangle_outline(spiked)) is None
    np.testing.assert_array_equal(untangle_outline(circle), circle)


def test_motion_between_measures_centroid_travel_and_turn():
    centroid = np.array([10.0, 0.0, 0.0])
    a = np.zeros(6)
    b = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 90.0])  # 90 degrees about z through the origin
    travel, turn = motion_between(a, b, centroid)
    assert turn == pytest.approx(90.0)
    assert travel == pytest.approx(10.0 * np.sqrt(2))


def test_spline_knows_the_chords_it_draws_across_gaps():
    from fluorogui.core.outlines.spline import OutlineSpline

    th = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    circle = 100 + 40 * np.column_stack([np.cos(th), np.sin(th)])  # points ~0.63 px apart
    keep = ~((th > 1.0) & (th < 1.6))  # a missing arc of ~24 px: the spline bridges it
    spline = OutlineSpline.fit(circle[keep])
    assert len(spline.gaps) == 1
    samples = spline.sample(300)
    kept = spline.sample(300, skip_gaps=True)
    assert len(samples) - len(kept) == pytest.approx(300 * 23.5 / spline.length_px, abs=3)
    on_chord = np.array([not np.any(np.all(np.isclose(p, kept), axis=1)) for p in samples])
    angle = np.arctan2(samples[on_chord, 1] - 100, samples[on_chord, 0] - 100)
    assert angle.min() > 0.99 and angle.max() < 1.61  # exactly the samples across the missing arc
    assert len(OutlineSpline.fit(circle).gaps) == 0
