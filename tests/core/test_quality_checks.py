"""The checks by name (what a measurement of each check's precision counts), and a
component partly beyond the field of view judged on what is visible: flagged only when too
little is left or its pose is loose, naming the loosest direction from its own SD."""
from fluorogui.core.matching.quality import CHECKS, Quality, QualityThresholds, failed_checks, judge
from fluorogui.core.status import Status


def test_failed_checks_are_named():
    q = Quality(False, [0.9, 0.12], [0.97, 0.6], [0.5, 0.95], jump_mm=30.0, jump_deg=3.0)
    names = [name for name, _ in failed_checks(q, thresholds=QualityThresholds(), typical_view_mm=0.12)]
    assert names == ["converged", "residual", "edge_support", "outline_support", "jump"]
    assert set(names) <= set(CHECKS)
    assert failed_checks(Quality(True, [0.1, 0.1], [0.99, 0.99], [0.99, 0.99])) == []


def _partial(outside, sd):
    return Quality(True, [0.1, 0.1], [0.99, 0.99], [0.99, 0.99], outside_field=[0.0, outside], sd=sd)


def test_a_partly_visible_component_passes_while_its_pose_is_pinned():
    pinned = [0.01, 0.01, 0.02, 0.02, 0.03, 0.05]
    assert judge(_partial(0.3, pinned)) == (Status.MATCHED, "")  # 70 % visible, SD 0.05 deg at most


def test_a_loose_pose_is_flagged_naming_the_loosest_direction():
    loose = [0.01, 0.01, 0.02, 0.02, 0.03, 0.9]
    status, reason = judge(_partial(0.3, loose))
    assert status == Status.NEEDS_REVIEW
    assert reason == ("only 70 % of the model outline is visible in view 2; its rotation about the model's z axis "
                      "(gamma) is uncertain to ±0.9 °")


def test_the_partly_visible_rule_judges_the_bodys_turns_not_the_euler_angles():
    # the real femur at frame 260 (93 % visible in view 2): its Euler alpha and beta SDs are
    # 1.0 deg, as in every frame of the sequence (the angles' coupling), its turns about its
    # own axes 0.07-0.21 deg; it lies 0.07 mm / 0.33 deg from the region fit
    euler = [0.063, 0.11, 0.037, 0.996, 1.008, 0.109]
    body = [0.062, 0.121, 0.041, 0.067, 0.208, 0.098]
    q = Quality(True, [0.13, 0.14], [0.99, 0.99], [0.99, 0.99], outside_field=[0.0, 0.07], sd=euler, sd_body=body)
    assert judge(q) == (Status.MATCHED, "")
    q.sd_body = [0.062, 0.121, 0.041, 0.067, 0.6, 0.098]
    assert judge(q)[1] == ("only 93 % of the model outline is visible in view 2; its turn about the model's y axis "
                           "is uncertain to ±0.6 °")
    assert judge(Quality(True, [0.13, 0.14], [0.99, 0.99], [0.99, 0.99], outside_field=[0.0, 0.07],
                         sd=euler))[0] == Status.NEEDS_REVIEW  # without the body's SDs: the Euler angles'


def test_a_projects_quality_keeps_undetermined_sds_as_none():
    q = Quality(True, [0.1], [0.9], [0.9], sd=[0.1] * 5 + [float("inf")], sd_body=[float("inf")] + [0.2] * 5)
    d = q.to_dict()
    assert d["sd"][5] is None and d["sd_body"][0] is None and d["sd_body"][1] == 0.2


def test_too_little_visible_is_flagged_whatever_the_sd():
    t = QualityThresholds()
    status, reason = judge(_partial(1.0 - t.min_visible_share + 0.05, [0.01] * 6))
    assert status == Status.NEEDS_REVIEW and "is needed" in reason
    assert judge(_partial(0.01, None)) == (Status.MATCHED, "")  # 1 % beyond: taken as fully visible


def _views():
    from fluorogui.simulation.protocols import dual_orthogonal_views

    return dual_orthogonal_views()


def test_a_weak_view_is_named_only_when_its_edges_are_all_that_fails():
    from fluorogui.core.matching.quality import weak_view

    q = Quality(True, [0.1, 0.1], [0.6, 0.97], [0.99, 0.99])
    assert weak_view(failed_checks(q), q) == 0
    both = Quality(True, [0.1, 0.1], [0.6, 0.7], [0.99, 0.99])  # both views: not one weak view
    assert weak_view(failed_checks(both), both) is None
    also = Quality(True, [0.1, 0.1], [0.6, 0.97], [0.5, 0.99])  # the outline does not fit either
    assert weak_view(failed_checks(also), also) is None


def test_a_weak_view_flags_only_what_its_edges_and_the_other_view_leave_loose():
    import numpy as np

    from fluorogui.core.matching.quality import weak_view_problem

    views = _views()
    tight = np.eye(3) * 0.05 ** 2
    assert weak_view_problem(0, views, tight, [0.05] * 3 + [0.1, 0.1, 0.1], edge=0.6) == ""  # pinned: passes
    n = np.asarray(views[1].normal, float)
    loose = tight + 0.6 ** 2 * np.outer(n, n)  # along view 2's beam, which view 2 cannot see
    text = weak_view_problem(0, views, loose, [0.6] * 3 + [0.1, 0.1, 0.1], edge=0.6)
    assert text == ("view 1 has little edge contrast (only 60 % of the model outline lies on image edges "
                    "there); judged by the other view and the edges view 1 has, its depth along view 2's axis is "
                    "uncertain to ±0.6 mm")
    turned = weak_view_problem(0, views, tight, [0.05] * 3 + [0.1, 0.9, 0.1], edge=0.6)
    assert turned.endswith("its turn about the model's y axis is uncertain to ±0.9 °")


def test_the_stretches_of_a_weak_view_without_edges_are_hidden_the_rest_kept():
    import cv2
    import numpy as np

    from fluorogui.core.matching.quality import edge_support, hidden_where_no_edges

    image = np.full((120, 160), 0.8, np.float32)
    cv2.rectangle(image, (40, 30), (120, 90), 0.2, -1)  # a dark block: edges all round ...
    image[70:, :] = 0.8 * 0.03 + image[70:, :] * 0  # ... but its lower part washed out (no contrast left)
    outline = np.array([(40, 30), (120, 30), (120, 90), (40, 90)], float)
    dense = np.concatenate([np.linspace(outline[i], outline[(i + 1) % 4], 80, endpoint=False) for i in range(4)])
    share = edge_support(image, dense)
    assert 0.4 < share < 0.8
    hidden = hidden_where_no_edges(image, dense, None, tol_px=1.5)
    covered = hidden[np.round(dense[:, 1]).astype(int), np.round(dense[:, 0]).astype(int)]
    assert covered[dense[:, 1] >= 75].all()  # the washed-out stretch
    assert not covered[dense[:, 1] <= 60].any()  # the edges that are there stay
