"""Tracking the demo knee bend: right poses are matched, wrong ones are never shown as
matched, bad frames are flagged and skipped, and a killed run resumes."""
from __future__ import annotations

import numpy as np
import pytest

from fluorogui.core.projection.pose import pose_error, rotation_matrix
from fluorogui.core.records import PoseRecord
from fluorogui.workflow import FrameState, Session
from fluorogui.workflow.framematch import turned


def _error(result, truth):
    e = pose_error(result.pose, truth[result.frame][result.component])
    return np.abs(e[:3]).max(), np.abs(e[3:]).max()


@pytest.mark.slow
def test_demo_frames_1_to_3_track_onto_the_truth(demo, truth):
    """The issue's demo case: from a matched frame 0, frames 1-3 were converged 6-21 degrees
    off and shown as matched. Now they land within 0.006 mm / 0.022 deg (measured)."""
    session = Session.open(demo)
    known = truth(session)
    results = list(session.track(first=1, components="both"))
    assert [(r.frame, r.component) for r in results] == [(f, c) for f in (1, 2, 3) for c in ("femoral", "tibial")]
    for r in results:
        mm, deg = _error(r, known)
        assert r.status == "matched", (r.frame, r.component, r.reason)
        # measured: at most 0.0055 mm (tibial, frame 1) and 0.021 deg (tibial, frame 2)
        assert mm < 0.011 and deg < 0.042, (r.frame, r.component, mm, deg)
        # measured: every model point on an image edge but one of 1300 (femur, frame 2, view 1)
        assert r.quality is not None and min(r.quality.edge_support) > 0.998, r.quality
    assert session.frame_states() == [FrameState.MATCHED] * 4
    # stored: status, reason, quality and automatic (unreviewed) outlines
    record = session.pose_record("femoral", 2)
    assert record.status == "matched" and record.match.quality["edge_support"]
    assert not session.outline_record((2, 0, "femoral")).reviewed


@pytest.mark.slow
def test_converged_wrong_pose_is_flagged_never_matched(demo, truth):
    """A start 15 deg off converges in a false minimum. Without recovery and the probe it
    must come back as needs_review with a reason; with them (the defaults) a wrong start
    never ends as a wrong pose shown as matched: both starts here are recovered and matched
    at the truth - including the tibial tray turned 25 deg about its stem, a false minimum
    that passes every absolute check (measured 22.5 deg off with 0.11 / 0.07 mm residuals,
    edge support 0.95)."""
    session = Session.open(demo)
    known = truth(session)
    settings = session.settings
    settings.tracking.recover = settings.tracking.probe = False
    session.set_settings(settings)

    def wrong_start(component, axis, degrees):
        pose = known[1][component]
        R = rotation_matrix(*pose[3:])
        return turned(pose, session.mesh(component).centroid, R[:, axis], degrees)

    session.set_pose("femoral", 1, wrong_start("femoral", 0, 15.0))
    femur = session.match(1, "femoral")[0]
    mm, deg = _error(femur, known)
    assert deg > 10.0  # really wrong (measured 14.9 deg)
    assert femur.match.optimiser_converged and not femur.match.converged, femur.match.message  # its own checks
    assert femur.status == "needs_review" and "image edges" in femur.reason
    assert session.pose_record("femoral", 1).needs_review
    assert session.frame_state(1) == FrameState.NEEDS_REVIEW

    # the defaults: recovery and the probe. Each wrong start must end matched at the truth
    # (measured: femoral 0.0045 mm / 0.0054 deg, tibial 0.0066 mm / 0.0276 deg; a flag
    # instead would be honest but is not what happens, so it fails here too). The tray's
    # 0.0276 deg was 0.0118 when recovery's search fitted its candidate on Canny outlines
    # before the match made that fit again: the match ends within the objective's noise
    # floor of wherever it starts (a second pass from there did not move it)
    session.set_settings(type(settings)())
    for component, axis, degrees in (("femoral", 0, 15.0), ("tibial", 2, -25.0)):
        session.set_pose(component, 1, wrong_start(component, axis, degrees))
        result = session.match(1, component)[0]
        mm, deg = _error(result, known)
        assert result.status == "matched", (component, result.status, result.reason, mm, deg)
        assert mm < 0.013 and deg < 0.055, (component, mm, deg)


@pytest.mark.slow
def test_missing_image_is_flagged_and_tracking_goes_on(demo):
    session = Session.open(demo)
    session.project.sequences[1].paths[2].unlink()  # view 2 of frame 2
    results = list(session.track(first=1, components="tibial"))
    by_frame = {r.frame: r for r in results}
    assert by_frame[1].status == "matched" and by_frame[3].status == "matched"
    assert by_frame[2].status == "failed" and "file not found" in by_frame[2].reason
    assert session.pose_record("tibial", 2).status == "failed"
    assert session.frame_state(2) == FrameState.NEEDS_REVIEW


def test_unequal_camera_sequences_flag_the_frames_one_view_lacks(demo):
    session = Session.open(demo)
    del session.project.sequences[0].paths[3]
    results = list(session.track([3], components="tibial"))
    assert results[0].status == "failed" and "view 1" in results[0].reason and "has 3 images" in results[0].reason


@pytest.mark.slow
def test_accepted_start_frame_stays_accepted_and_resume_keeps_matched_frames(demo):
    session = Session.open(demo)
    session.set_reviewed("femoral", 0, True)
    first = list(session.track([1, 2], components="femoral", autosave=True))
    assert session.pose_record("femoral", 0).reviewed
    assert all(r.status == "matched" for r in first)
    # a new run (e.g. after the process was killed) resumes: frames 1-2 are kept, 3 is tracked
    again = Session.open(demo)
    resumed = list(again.track(first=0, components="femoral"))
    assert [(r.frame, r.kept) for r in resumed] == [(0, True), (1, True), (2, True), (3, False)]
    assert resumed[-1].status == "matched"
    # redo matches them again, but never an accepted pose
    redone = list(again.track(first=0, components="femoral", redo=True))
    assert [(r.frame, r.kept) for r in redone] == [(0, True), (1, False), (2, False), (3, False)]


@pytest.mark.slow
def test_store_never_overwrites_accepted_poses_or_reviewed_outlines(demo):
    session = Session.open(demo)
    points = session.outline_points((0, 0, "tibial"))
    session.set_outline((0, 0, "tibial"), points + 0.25, "Edit outline")  # a user's edit: reviewed
    session.set_reviewed("femoral", 0, True)
    accepted = session.pose_record("femoral", 0).pose.copy()
    session.set_pose("femoral", 0, accepted + 1.0)  # moving it by hand reopens it
    assert not session.pose_record("femoral", 0).reviewed
    session.history.undo()
    results = session.match(0)
    assert session.pose_record("femoral", 0).reviewed
    np.testing.assert_array_equal(session.pose_record("femoral", 0).pose, accepted)
    np.testing.assert_array_equal(session.outline_points((0, 0, "tibial")), points + 0.25)
    assert {r.component for r in results} == {"femoral", "tibial"}
    session.history.undo()  # the match is one step
    assert session.pose_record("tibial", 0).match is not None


def test_session_addresses_frames_by_number_and_places_models(tmp_path):
    from fluorogui.simulation.demo import build_demo_project

    path = build_demo_project(tmp_path, frames=2, image_size=256)
    session = Session.open(path)
    session.project.frames = [10, 30]  # frame numbers, as in pairs.csv
    assert session.index_of(30) == 1 and session.neighbour(30, -5) == 10
    assert session.image(30, 1).shape == (256, 256)
    with pytest.raises(KeyError, match="frame 20"):
        session.match_job(20)
    # placement from two clicks: the centroid goes where the rays meet
    view1, view2 = session.views
    target = np.array([5.0, -3.0, 8.0])
    miss = session.place_at("tibial", 10, [view1.project(target[None])[0], view2.project(target[None])[0]])
    pose = session.pose("tibial", 10)
    from fluorogui.core.projection.pose import rotation_matrix

    centroid = rotation_matrix(*pose[3:]) @ session.mesh("tibial").centroid + pose[:3]
    assert miss < 1e-6 and np.allclose(centroid, target, atol=1e-6)
    assert session.pose_record("tibial", 10).status == "placed"
    # a frame with no pose of its own borrows the nearest earlier one
    np.testing.assert_array_equal(session.pose("tibial", 30), pose)
    session.orient("tibial", 10, (30.0, 0.0, 0.0))
    turned = session.pose("tibial", 10)
    assert turned[3] == 30.0
    again = rotation_matrix(*turned[3:]) @ session.mesh("tibial").centroid + turned[:3]
    assert np.allclose(again, target, atol=1e-9)
    session.history.undo()
    session.history.undo()
    assert session.pose_record("tibial", 10) is None and not session.dirty  # both steps undone


def test_pose_records_of_unknown_status_are_refused():
    with pytest.raises(ValueError, match="unknown pose status"):
        PoseRecord(np.zeros(6), None, status="great")


@pytest.mark.slow
def test_matched_pose_keeps_its_sd_in_the_project(demo):
    session = Session.open(demo)
    result = session.match(1, "femoral")[0]
    assert result.status == "matched" and len(result.to_json()["sd"]) == 6
    sd = np.array(result.sd)
    # measured 0.0020-0.0044 mm, 0.0047-0.0056 deg (the error: 0.0041 mm, 0.0053 deg)
    assert np.all(sd > 0) and np.all(sd[:3] < 0.009) and np.all(sd[3:] < 0.0113), sd
    session.save()
    quality = Session.open(demo).pose_record("femoral", 1).match.quality
    np.testing.assert_allclose(quality["sd"], sd)
    # the body's covariance too (for the knee's SDs): its diagonal is the body's SDs (kept to 1e-5)
    np.testing.assert_allclose(np.sqrt(np.diag(quality["cov_body"])), quality["sd_body"], rtol=0, atol=1e-5)


def test_an_automatic_outline_keeps_its_point_weights_in_the_project_until_edited(demo):
    from fluorogui.workflow.results import FrameResult

    session = Session.open(demo)
    key = (0, 1, "tibial")
    points = session.outline_points(key)
    weights = np.linspace(0.5, 2.0, len(points))  # as the rim refinement gives them
    pose = session.pose_record("tibial", 0).pose
    session.store(FrameResult(0, "tibial", pose, "matched", outlines=[None, points], outline_weights=[None, weights]))
    session.save()
    session = Session.open(demo)
    record = session.project.records[key]
    np.testing.assert_array_equal(record.weights, weights)
    assert np.allclose(session.spline(key).point_weights[1], weights / weights.mean())
    assert session.project.records[(0, 0, "tibial")].weights is None
    session.set_outline(key, record.points.copy(), "Accept outline")  # the same points, now reviewed
    assert session.project.records[key].reviewed
    np.testing.assert_array_equal(session.project.records[key].weights, weights)
    session.set_outline(key, record.points + 0.25)  # an edit: the fits no longer describe these points
    assert session.project.records[key].weights is None and session.spline(key).point_weights is None
    session.history.undo()
    np.testing.assert_array_equal(session.project.records[key].weights, weights)


@pytest.mark.slow
def test_a_second_orientation_that_fits_within_the_probe_ratio_is_flagged_ambiguous(demo, truth):
    """The ambiguity probe's flag, end to end (no other test reaches it): in a frame with no
    matched frame before it (frame 0: the probe runs), the tray turned 25 deg about its stem
    is recovered at the truth and the probe, turned 20 deg either way about the stem, finds
    a second orientation that passes every check (measured: 15 deg away, outline distance
    0.30 mm against 0.05 mm). With ``probe_ratio`` above that ratio the two count as fitting
    alike: the truth is kept, flagged ambiguous, saying how far apart they are."""
    session = Session.open(demo)
    known = truth(session)
    settings = session.settings
    settings.tracking.probe_ratio = 10.0
    session.set_settings(settings)
    pose = known[0]["tibial"]
    start = turned(pose, session.mesh("tibial").centroid, rotation_matrix(*pose[3:])[:, 2], -25.0)
    session.set_pose("tibial", 0, start)
    result = session.match(0, "tibial")[0]
    mm, deg = _error(result, known)
    assert result.status == "needs_review" and "ambiguous" in result.failed, (result.status, result.reason)
    assert result.reason.startswith("ambiguous: another orientation") and "° away" in result.reason
    assert mm < 0.013 and deg < 0.055, (mm, deg)  # the pose kept is the truth
