"""The checks by name (what a measurement of each check's precision counts), and a
component partly beyond the field of view judged on what is visible: flagged only when too
little is left or its pose is loose, naming the loosest direction from its own SD."""
from fluorogui.core.matching.quality import CHECKS, Quality, QualityThresholds, failed_checks, judge
from fluorogui.core.status import Status


def test_failed_checks_are_named():
    q = Quality(False, [0.9, 0.12], [0.97, 0.6], [0.5, 0.95], jump_mm=30.0, jump_deg=3.0)
    names = [name for name, _ in failed_checks(q, QualityThresholds(), typical_view_mm=0.12)]
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


def test_too_little_visible_is_flagged_whatever_the_sd():
    t = QualityThresholds()
    status, reason = judge(_partial(1.0 - t.min_visible_share + 0.05, [0.01] * 6))
    assert status == Status.NEEDS_REVIEW and "is needed" in reason
    assert judge(_partial(0.01, None)) == (Status.MATCHED, "")  # 1 % beyond: taken as fully visible
