"""A sequence's rim judgement rests on its matched frames, not on its first attempt: a
clear step is kept at once, but one view that fits soft among steps, or a frame that
fails its checks, does not decide whether every later frame's outline is moved."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from fluorogui.core.outlines.rim import STEP, RimModel, is_soft
from fluorogui.core.status import Status
from fluorogui.simulation.protocols import two_views
from fluorogui.workflow import framematch
from fluorogui.workflow.framematch import RIM_JUDGE_FRAMES, ComponentInput, FrameMatcher, RimJudgement
from fluorogui.workflow.settings import WorkflowSettings

SOFT = RimModel(1.2, 1.2)


def test_a_clear_step_settles_at_once_anything_else_on_the_median_of_three():
    judgement = RimJudgement(3)
    first = judgement.for_attempt()
    assert first == [None, None, None] and judgement.for_attempt() is not first  # each judges its own
    judgement.add([SOFT, STEP, None])  # view 3 given (reviewed) in this frame
    assert judgement.settled == [None, STEP, None]  # a clear step is kept at once ...
    judgement.add(None)  # (a result without models does not count)
    judgement.add([RimModel(2.0, 1.3), SOFT, None])  # ... and not judged again
    assert judgement.for_attempt() == [None, STEP, None] and RIM_JUDGE_FRAMES == 3
    judgement.add([RimModel(5.0, 1.3), None, RimModel(1.0, 1.4)])
    settled = judgement.for_attempt()
    assert settled == [RimModel(2.0, 1.3), STEP, None]  # one soft frame of three does not decide
    assert not any(is_soft(m) for m in settled[:2])
    assert judgement.for_attempt() is not settled  # view 3 still judges in each frame
    judgement.add([SOFT, SOFT, SOFT])
    judgement.add([SOFT, SOFT, RimModel(1.5, 1.2)])
    settled = judgement.for_attempt()
    assert settled == [RimModel(2.0, 1.3), STEP, SOFT] and is_soft(settled[2])  # two soft frames of three do
    assert judgement.for_attempt() is settled  # every later attempt shares it


def test_frame_matcher_reuses_the_models_only_after_three_matched_frames(monkeypatch):
    """Scripted frames, two views: in view 1 the first frame fails its checks with a soft
    fit, the second matches soft, the next two match with steps; from the fifth on the
    loop is handed the settled (step) model and fits nothing. View 2 is a clear step
    from the first matched frame on, and is not judged again."""
    script = {1: (SOFT, Status.NEEDS_REVIEW), 2: (SOFT, Status.MATCHED), 3: (STEP, Status.MATCHED),
              4: (STEP, Status.MATCHED),
              5: (SOFT, Status.MATCHED), 6: (SOFT, Status.MATCHED)}
    handed: dict[int, list] = {}
    state = {"frame": 0}

    def fake_loop(images, views, mesh, start, *, rim_models, **_):
        rims = rim_models
        frame = state["frame"]
        handed[frame] = list(rims)
        for k in range(len(rims)):
            if rims[k] is None:  # judged here, as segment_and_match fills the list
                rims[k] = script[frame][0] if k == 0 else STEP
        return SimpleNamespace(pose=np.zeros(6), converged=True, per_view_mean_mm=[0.05, 0.05], outlines_px=None,
                               splines=[], image_outlines=None, outline_weights=None, sd=None, sd_body=None, message="",
                               optimiser_converged=True, failed=[])

    monkeypatch.setattr(framematch, "segment_and_match", fake_loop)
    monkeypatch.setattr(framematch, "assess", lambda *a, **k: None)
    monkeypatch.setattr(framematch, "failed_checks", lambda *a, **k: (
        [] if script[state["frame"]][1] == Status.MATCHED else [("residual", "scripted")]))
    settings = WorkflowSettings()
    settings.tracking.recover = settings.tracking.probe = False
    matcher = FrameMatcher(two_views(image_size=(512, 512), pitch=315.0 / 512), settings)
    job = ComponentInput("femoral", SimpleNamespace(), np.zeros(6))
    statuses = []
    for frame in sorted(script):
        state["frame"] = frame
        statuses.append(matcher.match_component(frame, [np.zeros((512, 512))] * 2, job).status)
    assert statuses == [Status.NEEDS_REVIEW] + [Status.MATCHED] * 5
    assert handed[1] == handed[2] == [None, None]  # judged in each frame itself
    assert handed[3] == handed[4] == [None, STEP]  # view 2: frame 2's clear step
    assert handed[5] == handed[6] == [STEP, STEP]  # view 1: the median of frames 2-4, not frame 1's soft fit


def test_the_attempts_of_a_frame_after_a_matched_one_start_from_its_models(monkeypatch):
    """Within a frame the probes after a matched attempt are handed its rim models rather
    than judging the same images again; an attempt that fails its checks hands nothing on,
    and the next frame judges afresh (its models are not settled yet)."""
    handed: list[list] = []
    statuses = iter([Status.NEEDS_REVIEW] + [Status.MATCHED] * 6)

    def fake_loop(images, views, mesh, start, *, rim_models, **_):
        rims = rim_models
        handed.append(list(rims))
        for k in range(len(rims)):
            if rims[k] is None:
                rims[k] = RimModel(1.0 + len(handed), 1.2)  # a model per judging attempt
        return SimpleNamespace(pose=np.zeros(6), converged=True, per_view_mean_mm=[0.05, 0.05], outlines_px=None,
                               objective_mm=0.05, weakest_rotation_axis=lambda: np.array([0.0, 0.0, 1.0]),
                               splines=[], image_outlines=None, outline_weights=None, sd=None, sd_body=None, message="",
                               optimiser_converged=True, failed=[])

    monkeypatch.setattr(framematch, "segment_and_match", fake_loop)
    monkeypatch.setattr(framematch, "assess", lambda *a, **k: None)
    monkeypatch.setattr(framematch, "failed_checks", lambda *a, **k: (
        [] if next(statuses) == Status.MATCHED else [("residual", "scripted")]))
    matcher = FrameMatcher(two_views(image_size=(512, 512), pitch=315.0 / 512), WorkflowSettings())
    job = ComponentInput("femoral", SimpleNamespace(centroid=np.zeros(3)), np.zeros(6))
    first = matcher.match_component(0, [np.zeros((512, 512))] * 2, job)
    # the start fails its checks, a turned start matches, then the two probes (the same pose)
    assert first.status == Status.MATCHED and len(handed) == 4
    assert handed[0] == handed[1] == [None, None]  # each judges: the failed one hands nothing on
    assert handed[2] == handed[3] == [RimModel(3.0, 1.2)] * 2  # the matched attempt's models
    matcher.match_component(1, [np.zeros((512, 512))] * 2, job)
    assert handed[4] == [None, None]  # another frame's images: judged again
