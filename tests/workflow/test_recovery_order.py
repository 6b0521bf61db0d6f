"""Which starts recovery tries, in which order: after a jump of several frames the searches
come first (the prediction extrapolates further than the motion was seen); between
neighbouring frames the prediction, the last pose, the search near the prediction, the
turned starts and the whole-image search, as before. After a jump the search near the
prediction looks where the images located the component, when they did. A component
matched again because the other one moved far from its mask starts from its own first
match, without searching again, and its time counts both rounds."""
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
IMAGES = [np.zeros((4, 4)), np.zeros((4, 4))]


def _labels(gap: int, found=(NEAR, WHOLE)) -> tuple[list[str], list]:
    def find_near(images, component, mesh, pose, cancel=None):
        return found[0] if pose is not None else found[1]

    matcher = FrameMatcher(VIEWS, WorkflowSettings(), find_near)
    job = ComponentInput("tibial", SimpleNamespace(centroid=np.zeros(3)), PREDICTED, LAST, gap=gap,
                         axis=np.array([0.0, 0.0, 1.0]))
    starts = list(matcher._starts(IMAGES, job, None))
    return [label for label, _ in starts], starts


def test_after_a_jump_the_searches_come_first():
    labels, starts = _labels(NEAR_FIRST_GAP + 1)
    assert labels == ["find near the prediction", "find implants", "", "last pose"]
    np.testing.assert_array_equal(starts[0][1], NEAR)
    np.testing.assert_array_equal(starts[2][1], PREDICTED)
    # a search that places nothing is passed over
    labels, _ = _labels(NEAR_FIRST_GAP + 1, found=(None, WHOLE))
    assert labels == ["find implants", "", "last pose"]
    # a near search's candidates (best first) are starts in turn
    labels, starts = _labels(NEAR_FIRST_GAP + 1, found=([NEAR, NEAR + 1.0], WHOLE))
    assert labels == ["find near the prediction"] * 2 + ["find implants", "", "last pose"]
    np.testing.assert_array_equal(starts[1][1], NEAR + 1.0)
    labels, _ = _labels(NEAR_FIRST_GAP + 1, found=([], WHOLE))
    assert labels == ["find implants", "", "last pose"]


def test_where_the_images_located_it_and_the_search_there_placed_it_the_whole_image_is_not_searched():
    def labels(found_near, located):
        matcher = FrameMatcher(VIEWS, WorkflowSettings(), lambda images, c, mesh, pose, cancel=None:
                               found_near if pose is not None else WHOLE)
        job = ComponentInput("tibial", SimpleNamespace(centroid=np.zeros(3)), PREDICTED, LAST, gap=5, located=located)
        return [label for label, _ in matcher._starts(IMAGES, job, None)]

    assert labels(NEAR, PREDICTED + 10.0) == ["find near the prediction", "", "last pose"]
    assert labels(None, PREDICTED + 10.0) == ["find implants", "", "last pose"]  # nothing placed there
    assert labels(NEAR, None) == ["find near the prediction", "find implants", "", "last pose"]  # not located


def test_only_the_first_start_runs_the_whole_loop(monkeypatch):
    """After a jump every start is a recovery start, the prediction too (it extrapolates
    further than the motion was seen), even where the searches placed nothing: the shorter
    loop. (At frame 240 of the real sequence the whole loop from the prediction took 1.9 s.)"""
    loops = []

    def attempt(self, images, job, start, occluded, cancel, loop=None):
        loops.append(None if loop is None else loop.max_passes)
        return FrameResult(0, job.component, start, Status.NEEDS_REVIEW, "no")

    monkeypatch.setattr(FrameMatcher, "attempt", attempt)
    settings = WorkflowSettings()
    for gap, found, expected in ((1, NEAR, [None, 3]), (5, NEAR, [3, 3]), (5, None, [3])):
        loops.clear()
        def find_near(images, c, mesh, pose, cancel=None, found=found):
            return found if pose is not None else None

        matcher = FrameMatcher(VIEWS, settings, find_near)
        job = ComponentInput("tibial", SimpleNamespace(centroid=np.zeros(3)), PREDICTED, None, gap=gap, probe=False)
        matcher.match_component(0, IMAGES, job)
        assert loops[:len(expected)] == expected, (gap, loops)


def test_recovery_stops_where_only_the_visible_share_fails(monkeypatch):
    """A pose that fits but is flagged because too little of the component is in view (or
    that leaves its pose loose) is flagged alike from every start: no more are tried. Any
    other failure goes on to the next start."""
    tried = []

    def attempt_failing(failed):
        def attempt(self, images, job, start, occluded, cancel, loop=None):
            tried.append(start)
            return FrameResult(0, job.component, start, Status.NEEDS_REVIEW, "no", failed=list(failed))
        return attempt

    for failed in (["visible"], ["residual", "visible"], ["edge_support"]):
        tried.clear()
        monkeypatch.setattr(FrameMatcher, "attempt", attempt_failing(failed))
        matcher = FrameMatcher(VIEWS, WorkflowSettings(), lambda images, c, mesh, pose, cancel=None: NEAR)
        job = ComponentInput("tibial", SimpleNamespace(centroid=np.zeros(3)), PREDICTED, LAST, gap=1, probe=False)
        result = matcher.match_component(0, IMAGES, job)
        assert result.status == Status.NEEDS_REVIEW
        assert (len(tried) == 1) == (failed == ["visible"]), (failed, len(tried))


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
    starts = matcher._starts(IMAGES, job, None)
    assert next(starts)[0] == "find near the prediction" and searched == [True]  # the whole image not yet


def test_a_second_round_starts_from_the_first_match(monkeypatch):
    """The femur is matched with the tibia masked at its prediction; the tibia then lands
    5 mm away, so the femur is matched again, from its own first match (its prediction
    is still what the jump is judged against)."""
    seen = []

    def match_component(self, frame, images, job, occluded=None, cancel=None):
        seen.append((job.component, None if job.first is None else job.first.copy(), job.start.copy()))
        pose = job.start + (5.0 if job.component == "tibial" else 0.5)
        return FrameResult(frame, job.component, pose, Status.MATCHED, "", seconds=0.25, attempts=1)

    monkeypatch.setattr(FrameMatcher, "match_component", match_component)
    monkeypatch.setattr(framematch, "occlusion_masks", lambda *a, **k: [np.zeros((4, 4), bool)] * 2)
    mesh = SimpleNamespace(centroid=np.zeros(3), radius=30.0)
    jobs = [ComponentInput("femoral", mesh, np.zeros(6)), ComponentInput("tibial", mesh, np.ones(6))]
    results = FrameMatcher(VIEWS, WorkflowSettings()).match_frame(0, None, jobs)
    assert (results["femoral"].seconds, results["femoral"].attempts) == (0.5, 2)  # both rounds
    # (the femur ended 0.5 mm / deg from where the tibia was masked with it: no second round there)
    assert [c for c, _, _ in seen] == ["femoral", "tibial", "femoral"]
    assert seen[0][1] is None and seen[2][1] is not None
    np.testing.assert_allclose(seen[2][1], np.full(6, 0.5))  # the first round's match
    np.testing.assert_allclose(seen[2][2], np.zeros(6))  # the prediction, for the jump check


def test_after_a_jump_the_search_looks_where_the_images_located_it():
    searched = []

    def find_near(images, component, mesh, pose, cancel=None):
        searched.append(None if pose is None else pose.copy())
        return NEAR

    located = PREDICTED + np.array([30.0, -20.0, 5.0, 0.0, 0.0, 0.0])
    job = ComponentInput("tibial", SimpleNamespace(centroid=np.zeros(3)), PREDICTED, LAST, gap=5, located=located)
    starts = FrameMatcher(VIEWS, WorkflowSettings(), find_near)._starts(IMAGES, job, None)
    assert next(starts)[0] == "find near the prediction"
    np.testing.assert_array_equal(searched[0], located)


def test_a_search_is_made_once_per_frame():
    """A search sees no masks: a second round in the same frame gets the first one's placements."""
    searched = []

    def find_near(images, component, mesh, pose, cancel=None):
        searched.append(pose is not None)
        return None  # nothing placed: every start after the searches is tried

    matcher = FrameMatcher(VIEWS, WorkflowSettings(), find_near)
    job = ComponentInput("tibial", SimpleNamespace(centroid=np.zeros(3)), PREDICTED, LAST, gap=5)
    for _ in range(2):
        assert [label for label, _ in matcher._starts(IMAGES, job, None)] == ["", "last pose"]
    assert searched == [True, False]
    list(matcher._starts([np.zeros((4, 4)), np.zeros((4, 4))], job, None))  # another frame's images
    assert searched == [True, False, True, False]


def test_tracking_locates_a_component_after_a_jump_only(monkeypatch):
    """Tracking hands the matcher the prediction moved to where the images put the
    component's centroid (``core.search.relocate``), compared with the images of its last
    matched frame, and only across a jump; the images read are kept for that."""
    from fluorogui.workflow import tracking

    reads, compared = [], []
    monkeypatch.setattr(tracking, "read_frame_images",
                        lambda frame, *a, **k: reads.append(frame) or [np.full((4, 4), frame, float)] * 2)

    def relocated(before, after, views, mesh, pose):
        compared.append((before[0][0, 0], after[0][0, 0]))
        return np.array([10.0, 20.0, 30.0])

    monkeypatch.setattr(tracking, "relocated_centroid", relocated)
    mesh = SimpleNamespace(centroid=np.zeros(3))
    job = tracking.TrackJob(VIEWS, {"tibial": mesh}, [0, 1, 20], {}, ["tibial"], WorkflowSettings())
    motion = {"tibial": tracking.MotionModel(mesh.centroid)}
    for frame in (0, 1):
        motion["tibial"].add(frame, np.array([float(frame), 0, 0, 0, 0, 0]))
        job._images(frame)
    residuals = {"tibial": []}
    near = job._input("tibial", 2, motion, residuals, starts={}, images=job._images(2))
    far = job._input("tibial", 20, motion, residuals, starts={}, images=job._images(20))
    assert near.located is None and far.located is not None
    np.testing.assert_allclose(far.located, [10.0, 20.0, 30.0, 0.0, 0.0, 0.0])  # the prediction's turn kept
    assert compared == [(1.0, 20.0)]  # the last matched frame's images against this one's
    assert reads == [0, 1, 2, 20]  # frame 1's from memory


def test_after_a_jump_the_others_are_masked_where_their_search_places_them(monkeypatch):
    """After a jump the tibia's prediction extrapolates: the femur, matched first, is masked
    with the tibia where the search near it places it (made once, for the mask and for the
    tibia's own first start). The tibia lands within 1 mm of that: no second round.
    Between neighbouring frames the mask stays at the prediction and nothing is searched."""
    searched, masks = [], []

    def find_near(images, component, mesh, pose, cancel=None):
        searched.append((component, pose is not None))
        return NEAR if component == "tibial" else None  # the femur's: nothing near, nor in the whole image

    def occlusion_masks(views, others, near, mesh, margin_px=3):
        masks.append([np.asarray(pose).copy() for _, pose in others])
        return [np.zeros((4, 4), bool)] * 2

    def attempt(self, images, job, start, occluded, cancel, loop=None):
        pose = np.asarray(start, float) + (0.1 if job.component == "tibial" else 0.0)
        return FrameResult(0, job.component, pose, Status.MATCHED, "", rim_models=self._rims_for(images, job.component))

    monkeypatch.setattr(framematch, "occlusion_masks", occlusion_masks)
    monkeypatch.setattr(FrameMatcher, "attempt", attempt)
    mesh = SimpleNamespace(centroid=np.zeros(3), radius=30.0)
    jump = [("femoral", False), ("femoral", True), ("tibial", True)]
    for gap, tibia_masked_at, searches in ((NEAR_FIRST_GAP + 3, NEAR, jump), (1, PREDICTED, [])):
        searched.clear()
        masks.clear()
        jobs = [ComponentInput("femoral", mesh, np.zeros(6), gap=gap, probe=False),
                ComponentInput("tibial", mesh, PREDICTED, gap=gap, probe=False)]
        results = FrameMatcher(VIEWS, WorkflowSettings(), find_near).match_frame(0, IMAGES, jobs)
        np.testing.assert_array_equal(masks[0][0], tibia_masked_at)  # the femur's mask
        assert len(masks) == 2 and results["femoral"].attempts == 1  # no second round
        assert sorted(searched) == searches  # (component, near): each search once at most
