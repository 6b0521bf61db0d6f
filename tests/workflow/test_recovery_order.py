"""Which starts recovery tries, in which order: after a jump of several frames the searches
come first (the prediction extrapolates further than the motion was seen); between
neighbouring frames the prediction, the last pose, the search near the prediction, the
turned starts and the whole-image search, as before. A component matched again because
the other one moved far from its mask starts from its own first match."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from fluorogui.core.status import Status
from fluorogui.simulation.protocols import two_views
from fluorogui.workflow import framematch
from fluorogui.workflow.framematch import NEAR_FIRST_GAP, ComponentInput, FrameMatcher
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.settings import WorkflowSettings

VIEWS = two_views(image_size=(512, 512), pitch=315.0 / 512)
PREDICTED = np.array([0.0, 0.0, 0.0, 10.0, 0.0, 0.0])
LAST = np.array([3.0, 0.0, 0.0, 5.0, 0.0, 0.0])
NEAR, WHOLE = np.full(6, 1.0), np.full(6, 2.0)


def _labels(gap: int, found=(NEAR, WHOLE)) -> tuple[list[str], list]:
    def find_near(images, component, mesh, pose, cancel=None):
        return found[0] if pose is not None else found[1]

    matcher = FrameMatcher(VIEWS, WorkflowSettings(), find_near)
    job = ComponentInput("tibial", SimpleNamespace(centroid=np.zeros(3)), PREDICTED, LAST, gap=gap,
                         axis=np.array([0.0, 0.0, 1.0]))
    starts = list(matcher._starts(None, job, None))
    return [label for label, _ in starts], starts


def test_after_a_jump_the_searches_come_first():
    labels, starts = _labels(NEAR_FIRST_GAP + 1)
    assert labels == ["find near the prediction", "find implants", "", "last pose"]
    np.testing.assert_array_equal(starts[0][1], NEAR)
    np.testing.assert_array_equal(starts[2][1], PREDICTED)
    # a search that places nothing is passed over
    labels, _ = _labels(NEAR_FIRST_GAP + 1, found=(None, WHOLE))
    assert labels == ["find implants", "", "last pose"]


def test_between_neighbouring_frames_the_prediction_comes_first():
    labels, starts = _labels(1)
    assert labels == ["", "last pose", "find near the prediction", "turned start", "turned start", "find implants"]
    np.testing.assert_array_equal(starts[0][1], PREDICTED)


def test_starts_are_worked_out_only_when_the_ones_before_failed():
    searched = []

    def find_near(images, component, mesh, pose, cancel=None):
        searched.append(pose is not None)
        return NEAR

    matcher = FrameMatcher(VIEWS, WorkflowSettings(), find_near)
    job = ComponentInput("tibial", SimpleNamespace(centroid=np.zeros(3)), PREDICTED, LAST, gap=5)
    starts = matcher._starts(None, job, None)
    assert next(starts)[0] == "find near the prediction" and searched == [True]  # the whole image not yet


def test_a_second_round_starts_from_the_first_match(monkeypatch):
    """The femur is matched with the tibia masked at its prediction; the tibia then lands
    5 mm away, so the femur is matched again, from its own first match (its prediction
    is still what the jump is judged against)."""
    seen = []

    def match_component(self, frame, images, job, occluded=None, cancel=None):
        seen.append((job.component, None if job.first is None else job.first.copy(), job.start.copy()))
        pose = job.start + (5.0 if job.component == "tibial" else 0.5)
        return FrameResult(frame, job.component, pose, Status.MATCHED, "")

    monkeypatch.setattr(FrameMatcher, "match_component", match_component)
    monkeypatch.setattr(framematch, "occlusion_masks", lambda *a, **k: [np.zeros((4, 4), bool)] * 2)
    mesh = SimpleNamespace(centroid=np.zeros(3), radius=30.0)
    jobs = [ComponentInput("femoral", mesh, np.zeros(6)), ComponentInput("tibial", mesh, np.ones(6))]
    FrameMatcher(VIEWS, WorkflowSettings()).match_frame(0, None, jobs)
    # (the femur ended 0.5 mm / deg from where the tibia was masked with it: no second round there)
    assert [c for c, _, _ in seen] == ["femoral", "tibial", "femoral"]
    assert seen[0][1] is None and seen[2][1] is not None
    np.testing.assert_allclose(seen[2][1], np.full(6, 0.5))  # the first round's match
    np.testing.assert_allclose(seen[2][2], np.zeros(6))  # the prediction, for the jump check
