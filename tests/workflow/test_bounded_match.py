"""Recovery is bounded in time (issue 44: a start 54 mm off took 60 s, ten recovery starts each
fitting the rim models again): ``TrackingSettings.max_seconds`` after a component's match
began, recovery stops and the best result so far stays flagged, its reason saying so. The
first start and the probe run to their end (one start on soft-rim X-ray images can take
half a minute). Most tests run on a clock that each attempt moves on.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from fluorogui.core.cancel import OutOfTime, check_cancel, with_deadline
from fluorogui.core.status import Status
from fluorogui.simulation.protocols import two_views
from fluorogui.workflow import Session
from fluorogui.workflow.framematch import ComponentInput, FrameMatcher, RimJudgement
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.settings import WorkflowSettings

VIEWS = two_views(image_size=(512, 512), pitch=315.0 / 512)
PREDICTED = np.array([0.0, 0.0, 0.0, 10.0, 0.0, 0.0])
LAST = np.array([3.0, 0.0, 0.0, 5.0, 0.0, 0.0])
IMAGES = [np.zeros((4, 4)), np.zeros((4, 4))]


@pytest.fixture
def clock(monkeypatch):
    """A clock standing still until ``clock.now`` is moved on."""
    state = SimpleNamespace(now=1000.0)
    monkeypatch.setattr("time.perf_counter", lambda: state.now)
    return state


def _matcher(max_seconds: float = 20.0, probe: bool = False) -> tuple[FrameMatcher, ComponentInput]:
    settings = WorkflowSettings()
    settings.tracking.max_seconds = max_seconds
    matcher = FrameMatcher(VIEWS, settings, lambda images, c, mesh, pose, cancel=None: np.full(6, 1.0))
    matcher.rim_judgements["tibial"] = RimJudgement(2)
    job = ComponentInput("tibial", SimpleNamespace(centroid=np.zeros(3)), PREDICTED, LAST, gap=1, probe=probe)
    return matcher, job


def test_with_deadline_raises_out_of_time_after_it_and_the_callers_cancel_comes_first(clock):
    check = with_deadline(None, clock.now + 5.0)
    assert check() is False
    clock.now += 6.0
    with pytest.raises(OutOfTime):
        check_cancel(check)
    assert with_deadline(lambda: True, clock.now - 1.0)() is True  # cancelled, not out of time
    assert with_deadline(None, None) is None


def test_recovery_stops_at_the_limit_with_its_best_result_flagged(monkeypatch, clock):
    tried = []

    def attempt(self, images, job, start, occluded, cancel, loop=None):
        tried.append(start)
        check_cancel(cancel)  # as the optimisers and searches do
        clock.now += 8.0
        return FrameResult(0, job.component, start + len(tried), Status.NEEDS_REVIEW,
                           f"outline distance {len(tried)} mm", failed=["residual"])

    monkeypatch.setattr(FrameMatcher, "attempt", attempt)
    matcher, job = _matcher(max_seconds=20.0)
    result = matcher.match_component(0, IMAGES, job)
    assert len(tried) == 3  # at 0, 8 and 16 s; the fourth start finds the time up (24 s)
    assert result.status == Status.NEEDS_REVIEW and "time" in result.failed
    assert result.reason.startswith("stopped after 24 s: recovery may take 20 s (the tracking setting max_seconds)")
    assert result.reason.endswith("; outline distance 1 mm")  # the best result's own reason follows
    np.testing.assert_array_equal(result.pose, PREDICTED + 1)
    # without a limit every start is tried: the prediction, the last pose, the search, six
    # turned starts (about the model's axes) and the whole-image search
    tried.clear()
    matcher, job = _matcher(max_seconds=0.0)
    result = matcher.match_component(0, IMAGES, job)
    assert len(tried) == 10 and "stopped" not in result.reason


def test_a_recovery_start_is_stopped_at_its_next_check_but_the_first_runs_to_its_end(monkeypatch, clock):
    ends = []

    def attempt(self, images, job, start, occluded, cancel, loop=None):
        for _ in range(30):  # an optimiser's calls, a second each
            check_cancel(cancel)
            clock.now += 1.0
        ends.append(clock.now - 1000.0)
        return FrameResult(0, job.component, start, Status.NEEDS_REVIEW, "the match did not converge")

    monkeypatch.setattr(FrameMatcher, "attempt", attempt)
    matcher, job = _matcher(max_seconds=20.0)
    result = matcher.match_component(0, IMAGES, job)
    assert ends == [30.0]  # the first start ran past the limit; no other was begun
    assert result.status == Status.NEEDS_REVIEW and result.attempts == 1
    assert result.reason == ("stopped after 30 s: recovery may take 20 s (the tracking setting max_seconds); check "
                             "the start pose, or give outlines; the match did not converge")
    ends.clear()
    clock.now = 1000.0
    matcher, job = _matcher(max_seconds=45.0)
    result = matcher.match_component(0, IMAGES, job)
    assert ends == [30.0] and result.attempts == 2  # the second start stopped at 45 s, in its 16th call
    assert result.reason.startswith("stopped after 46 s")


def test_the_probe_of_a_match_runs_to_its_end(monkeypatch, clock):
    """A start matched after the limit is still probed for a second orientation."""
    match = SimpleNamespace(weakest_rotation_axis=lambda: np.array([0.0, 0.0, 1.0]), objective_mm=0.2)

    def attempt(self, images, job, start, occluded, cancel, loop=None):
        check_cancel(cancel)
        clock.now += 15.0
        if np.array_equal(start, PREDICTED):
            return FrameResult(0, job.component, start, Status.MATCHED, "", match=match)
        return FrameResult(0, job.component, start, Status.NEEDS_REVIEW, "no fit", match=match)  # the probes

    monkeypatch.setattr(FrameMatcher, "attempt", attempt)
    matcher, job = _matcher(max_seconds=10.0, probe=True)
    result = matcher.match_component(0, IMAGES, job)
    assert result.status == Status.MATCHED and result.attempts == 3 and result.reason == ""


def test_recovery_on_the_demo_stops_at_the_limit(demo):
    """A start 40 mm off the demo's femur: the first start fails, recovery searches and tries
    other starts until the limit (1 s here, 20 s by default), and the result says so. How long
    the real cases take is counted by ``tools/fuzz.py`` (``cli_cases.bounded_cases``)."""
    session = Session.open(demo)
    settings = session.settings
    settings.tracking.max_seconds = 1.0
    session.set_settings(settings)
    session.set_pose("femoral", 0, session.pose("femoral", 0) + [40, 0, 0, 0, 0, 0])
    result, = session.match(0, "femoral")
    assert result.status in (Status.NEEDS_REVIEW, Status.FAILED) and "time" in result.failed
    assert result.reason.startswith("stopped after ") and "s: recovery may take 1 s" in result.reason


def test_the_limit_is_a_stored_setting():
    settings = WorkflowSettings()
    assert settings.tracking.max_seconds == 20.0
    settings.tracking.max_seconds = 7.5
    assert WorkflowSettings.from_dict(settings.to_dict()).tracking.max_seconds == 7.5
