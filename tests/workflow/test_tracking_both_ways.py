"""Tracking in both directions: frames before the first one found are tracked back from it,
and a frame that fails forward is tracked again backward from the next match; results come
out once per frame and component, in frame order."""
import numpy as np
import pytest

import fluorogui.workflow.tracking as tracking
from fluorogui.core.projection.pose import motion_between
from fluorogui.core.search.find import Placement
from fluorogui.core.status import Status
from fluorogui.workflow import Session


def _errors(session, result, truth):
    return motion_between(result.pose, truth[result.frame][result.component], session.mesh(result.component).centroid)


@pytest.mark.slow
def test_frames_before_the_first_found_are_tracked_back_to_the_start(demo, truth, monkeypatch):
    """Find refuses frames 0 and 1 (as it does where the components overlap); tracking starts
    at frame 2 and goes back: every frame ends matched at the truth."""
    real_find = tracking.find_in_frame

    def refusing_find(frame, images, views, meshes, **kwargs):
        if frame < 2:
            return {c: Placement(c, None, False, [], float("nan"), [], "best overlap 0.92 is too low", 0.0, frame=frame)
                    for c in meshes}
        return real_find(frame, images, views, meshes, **kwargs)

    monkeypatch.setattr(tracking, "find_in_frame", refusing_find)
    session = Session.open(demo)
    session.project.poses.clear()  # nothing placed or matched: tracking starts by finding
    known = truth(session)
    results = list(session.track())
    assert [(r.frame, r.component) for r in results] == [(f, c) for f in range(4) for c in ("femoral", "tibial")]
    for r in results:
        mm, deg = _errors(session, r, known)
        assert r.status == Status.MATCHED and mm < 0.05 and deg < 0.05, (r.frame, r.component, r.reason, mm, deg)
    assert all(r.recovered.startswith("tracked back") for r in results if r.frame < 2)
    assert all(session.pose_record(c, f).status == Status.MATCHED for f in range(4) for c in ("femoral", "tibial"))


def test_a_frame_that_fails_forward_is_tracked_back_from_the_next_match(demo, truth, monkeypatch):
    """Frame 2's forward prediction is thrown 25 deg off and recovery is off, so it fails
    forward; frame 3 matches, and frame 2 is tracked back from it and ends matched."""
    session = Session.open(demo)
    settings = session.settings
    settings.tracking.recover = False
    settings.tracking.find_near = False
    session.set_settings(settings)
    real_input = tracking.TrackJob._input

    def thrown_off(self, c, frame, *args, **kwargs):
        job = real_input(self, c, frame, *args, **kwargs)
        if frame == 2 and c == "tibial":
            job.start = np.asarray(job.start, float) + np.array([0.0, 0.0, 0.0, 25.0, 0.0, 0.0])
        return job

    monkeypatch.setattr(tracking.TrackJob, "_input", thrown_off)
    known = truth(session)
    results = list(session.track(first=1, components="tibial"))
    assert [r.frame for r in results] == [1, 2, 3]
    by_frame = {r.frame: r for r in results}
    assert by_frame[2].status == Status.MATCHED and by_frame[2].recovered == "tracked back"
    for r in results:
        mm, deg = _errors(session, r, known)
        assert mm < 0.05 and deg < 0.05, (r.frame, mm, deg)
