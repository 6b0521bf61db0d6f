"""A sequence's rim judgement rests on several matched frames, not on its first attempt:
one view that fits soft among steps, or a frame that fails its checks, does not decide
whether every later frame's outline is moved."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from fluorogui.core.validation import two_views
from fluorogui.core.quality import MATCHED, NEEDS_REVIEW
from fluorogui.core.rim import STEP, RimModel, is_soft
from fluorogui.workflow import framematch
from fluorogui.workflow.framematch import RIM_JUDGE_FRAMES, ComponentInput, FrameMatcher, RimJudgement
from fluorogui.workflow.settings import WorkflowSettings

SOFT = RimModel(1.2, 1.2)


def test_median_of_the_matched_frames_decides_and_is_then_shared():
    judgement = RimJudgement(2)
    first = judgement.for_attempt()
    assert first == [None, None] and judgement.for_attempt() is not first  # each judges its own
    judgement.add([SOFT, STEP])  # one frame fits view 1 soft ...
    judgement.add(None)  # (a result without models does not count)
    judgement.add([None, None])
    judgement.add([STEP, RimModel(1.4, 1.3)])
    assert judgement.settled is None and RIM_JUDGE_FRAMES == 3
    judgement.add([RimModel(5.0, 1.3), RimModel(1.0, 1.4)])  # ... the other two steps
    settled = judgement.for_attempt()
    assert settled == [RimModel(5.0, 1.3), RimModel(1.4, 1.3)]
    assert [is_soft(m) for m in settled] == [False, True]
    assert judgement.for_attempt() is settled  # every later attempt shares (and fills) it
    judgement.add([SOFT, SOFT])
    assert judgement.for_attempt() == settled


def test_of_two_votes_the_sharper_wins_and_unjudged_views_stay_open():
    judgement = RimJudgement(3)
    judgement.add([SOFT, STEP, None])
    judgement.add([None, None, None])  # no vote
    judgement.add([STEP, None, None])  # view 2 given (reviewed) in this frame
    assert judgement.settled is None
    judgement.add([RimModel(1.3, 1.0), SOFT, None])
    assert judgement.settled == [RimModel(1.3, 1.0), STEP, None]


def test_frame_matcher_reuses_the_models_only_after_three_matched_frames(monkeypatch):
    """Scripted frames: the first fails its checks with a soft view, the second matches
    soft, the next two match with steps; from the fifth on the loop is handed the
    settled (step) model and fits nothing."""
    script = {1: (SOFT, NEEDS_REVIEW), 2: (SOFT, MATCHED), 3: (STEP, MATCHED), 4: (STEP, MATCHED),
              5: (SOFT, MATCHED), 6: (SOFT, MATCHED)}
    handed: dict[int, list] = {}
    state = {"frame": 0}

    def fake_loop(images, views, mesh, start, settings, loop, given, occluded, step, cancel, rims):
        frame = state["frame"]
        handed[frame] = list(rims)
        for k in range(len(rims)):
            if rims[k] is None:  # judged here, as segment_and_match fills the list
                rims[k] = script[frame][0]
        result = SimpleNamespace(cancelled=False, pose=np.zeros(6), converged=True, per_view_mean_mm=[0.05],
                                 outlines_px=None)
        return SimpleNamespace(result=result, splines=[], outlines=None)

    monkeypatch.setattr(framematch, "segment_and_match", fake_loop)
    monkeypatch.setattr(framematch, "assess", lambda *a, **k: None)
    monkeypatch.setattr(framematch, "judge", lambda *a, **k: (script[state["frame"]][1], ""))
    settings = WorkflowSettings()
    settings.tracking.recover = settings.tracking.probe = False
    matcher = FrameMatcher(two_views(image_size=(512, 512), pitch=315.0 / 512)[:1], settings)
    job = ComponentInput("femoral", SimpleNamespace(), np.zeros(6))
    statuses = []
    for frame in sorted(script):
        state["frame"] = frame
        statuses.append(matcher.match_component(frame, [np.zeros((512, 512))], job).status)
    assert statuses == [NEEDS_REVIEW] + [MATCHED] * 5
    assert all(handed[f] == [None] for f in (1, 2, 3, 4))  # judged in each frame itself
    assert handed[5] == handed[6] == [STEP]  # the median of frames 2-4, not frame 1's soft fit
