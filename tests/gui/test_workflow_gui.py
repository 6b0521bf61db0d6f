"""The app as a thin adapter over the workflow: Match both and Track both land on the demo
truth, the app and a script give the identical pose, a flagged frame is never shown as
matched, tracking keeps accepted frames and goes on past a bad one, cancel changes
nothing, find implants reports progress, and a project another program holds is not
opened behind its back."""
import json
import os
import socket

import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PySide6.QtWidgets import QFileDialog, QMessageBox  # noqa: E402

from fluorogui.core.projection.pose import pose_error  # noqa: E402
from fluorogui.core.records import PoseRecord  # noqa: E402
from fluorogui.core.status import Status
from fluorogui.gui.panels.timeline import STATE_COLOURS  # noqa: E402
from fluorogui.io.project.lock import lock_path  # noqa: E402
from fluorogui.workflow.session import FrameState, Session  # noqa: E402

TOL = 0.05  # mm and degrees


def truth(session, frame, name):
    return np.array(session.project.settings["demo_truth"][str(frame)][name])


def start_from_truth(session, frame, reviewed=False):
    """Frame ``frame`` matched at the truth (as a finished match would leave it)."""
    for name in session.components():
        session.set_record(name, frame, PoseRecord(truth(session, frame, name), None, reviewed=reviewed,
                                                   status=Status.MATCHED), "Match")


@pytest.mark.slow
def test_match_both_lands_on_the_demo_truth_and_undoes_in_one_step(window, fine_demo, qtbot):
    window.open_project(fine_demo)
    c, s = window.controller, window.controller.session
    before = {n: s.pose(n, 0) for n in s.components()}
    with qtbot.waitSignal(window.runner.finished, timeout=300000):
        assert window.match_both()
    for name in s.components():
        record = s.pose_record(name, 0)
        assert record.status == "matched", record.reason
        err = pose_error(record.pose, truth(s, 0, name))
        assert np.abs(err[:3]).max() < TOL and np.abs(err[3:]).max() < TOL, (name, err)
    assert window.timeline.state(0) == FrameState.MATCHED
    assert "femoral matched" in window.matcher.summary.text() and "tibial matched" in window.matcher.summary.text()
    assert window.matcher.plot.values  # the objective of the match
    sd = s.pose_record(c.component, 0).match.quality["sd"]  # the Pose tab shows the match's SDs
    assert len(sd) == 6 and [label.text() for label in window.pose_editor.sd_labels] == [f"± {v:.3f}" for v in sd]
    turns = s.pose_record(c.component, 0).match.quality["sd_body"][3:]  # ... and the body's own turns'
    assert window.pose_editor.body_sd.text().endswith(", ".join(f"{v:.3f}" for v in turns) + "°")
    # one undo step, through the Undo / Redo actions and back
    assert len(s.history) == 1
    window.edit.undo_action.trigger()
    for name in s.components():
        np.testing.assert_allclose(s.pose(name, 0), before[name])
        assert s.outline_record((0, 0, name)) is None
    assert window.timeline.state(0) != FrameState.MATCHED and not c.dirty
    window.edit.redo_action.trigger()
    assert all(s.pose_record(n, 0).status == "matched" for n in s.components())


@pytest.mark.slow
def test_track_both_from_a_matched_frame_keeps_it_and_lands_on_the_truth(window, fine_demo, qtbot):
    window.open_project(fine_demo)
    c, s = window.controller, window.controller.session
    start_from_truth(s, 0)
    for name in s.components():
        c.set_component(name)
        window.review.accept_pose()  # frame 0 accepted: tracking must keep it so
    assert window.timeline.state(0) == FrameState.REVIEWED
    kept = {n: s.pose_record(n, 0) for n in s.components()}
    shown, plotted = [], []
    window.frame_shown.connect(lambda frame: (shown.append(frame), plotted.append(list(window.matcher.plot.values))))
    bars = []
    window.runner.item.connect(lambda _item: bars.append(window.matcher.progress.text()))
    with qtbot.waitSignal(window.runner.finished, timeout=600000):
        assert window.track_both()
    for name in s.components():
        assert s.pose_record(name, 0) == kept[name] and s.pose_record(name, 0).reviewed
        for frame in (1, 2, 3):
            record = s.pose_record(name, frame)
            assert record.status == "matched", (frame, name, record.reason)
            err = pose_error(record.pose, truth(s, frame, name))
            assert np.abs(err[:3]).max() < TOL and np.abs(err[3:]).max() < TOL, (frame, name, err)
    assert window.timeline.states == [FrameState.REVIEWED] + [FrameState.MATCHED] * 3
    # the view followed the tracked frames, in order, to the last; it shows at most one per
    # event-loop pass, so a frame finished within the same pass as the next may be skipped
    followed = [k for k, frame in enumerate(shown) if frame in (1, 2, 3)]
    assert followed and shown[followed[-1]] == 3 and c.frame == 3
    assert [shown[k] for k in followed] == sorted(shown[k] for k in followed)
    assert all(plotted[k] for k in followed)  # with that frame's objective in the plot
    assert bars[0].startswith("1 / 3 frames") and "left" in bars[0]
    summary = window.matcher.summary.text()
    assert "3 matched, 0 need review, 0 failed" in summary and "(1–3)" in summary
    assert len(s.history) == 2 * len(s.components()) + 3  # set, accept; then one step per tracked frame
    c.set_frame(2)  # coming back to a tracked frame later: its objective is still plotted
    stored = s.pose_record(c.component, 2).match.history
    assert stored and window.matcher.plot.values == pytest.approx(stored)


@pytest.mark.slow
def test_the_app_and_a_script_give_the_identical_pose(window, demo, qtbot, tmp_path):
    script = Session.open(demo)  # the same project file, read before the app touches it
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    name = c.components()[0]
    with qtbot.waitSignal(window.runner.finished, timeout=300000):
        assert window.run_match()  # the match job through the worker thread
    results = script.match(0, name)
    assert results[0].status == s.pose_record(name, 0).status
    np.testing.assert_array_equal(s.pose_record(name, 0).pose, script.pose_record(name, 0).pose)
    np.testing.assert_array_equal(s.outline_points((0, 0, name)), script.outline_points((0, 0, name)))


@pytest.mark.slow
def test_a_flagged_frame_is_shown_as_needing_review_and_tracking_goes_on(window, demo, qtbot):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    settings = s.settings
    settings.tracking.find_near = False  # no global search in recovery (keeps the test short)
    s.set_settings(settings)
    start_from_truth(s, 0)
    from fluorogui.io.images import write_image

    blank = np.full((512, 512), 128, np.uint8)  # view 1 of frame 1 shows nothing to trace
    write_image(s.image_path(1, 0), blank)
    with qtbot.waitSignal(window.runner.finished, timeout=600000):
        assert window.track_both()
    assert s.frame_state(1) == FrameState.NEEDS_REVIEW
    assert all(s.pose_record(n, 2) is not None for n in s.components())  # tracking went past it
    summary = window.matcher.summary.text()
    assert "Needs review: frame 1" in summary or "Failed: frame 1" in summary
    assert c.frame == 1 and "first to review" in summary  # the view goes to the frame to review
    # the timeline paints it in the needs-review colour
    image = window.timeline.grab().toImage()
    rect = window.timeline.cell_rect(1)
    colour = image.pixelColor(int(rect.left()) + 3, int(rect.center().y()))
    assert colour == STATE_COLOURS[FrameState.NEEDS_REVIEW]
    assert "needs review" in window.timeline.notes[1] or "failed" in window.timeline.notes[1]
    # the reason in plain words, the model outline drawn as flagged
    status = window.matcher.status.text()
    name = c.component
    record = s.pose_record(name, 1)
    assert record.needs_review and record.reason and record.reason in status.replace("&#x27;", "'")
    assert "Error" not in status and "matched" not in status.split(name)[1].split("<br>")[0]
    assert all(panel.model_flagged(name) for panel in window.panels)
    # accepting a flagged pose is allowed: it becomes reviewed (green once both are)
    for n in s.components():
        c.set_component(n)
        window.review.accept_pose()
    assert s.frame_state(1) == FrameState.REVIEWED and window.timeline.state(1) == FrameState.REVIEWED
    assert not any(panel.model_flagged(name) for panel in window.panels)
    assert "accepted" in window.matcher.status.text()


@pytest.mark.slow
def test_cancelled_tracking_keeps_the_stored_frames_and_leaves_the_rest(window, demo, qtbot):
    window.open_project(demo)
    s = window.controller.session
    start_from_truth(s, 0)
    window.runner.item.connect(lambda _item: window.runner.cancel())  # cancel once frame 1 is stored
    with qtbot.waitSignal(window.runner.cancelled, timeout=600000):
        assert window.track_both()
    assert all(s.pose_record(n, 1) is not None for n in s.components())
    assert all(s.pose_record(n, 2) is None for n in s.components())  # the frame in progress: unchanged
    assert "Cancelled" in window.matcher.summary.text() and window.matcher.run_button.isEnabled()


def test_match_both_skips_an_accepted_pose(window, demo, qtbot):
    window.open_project(demo)
    s = window.controller.session
    start_from_truth(s, 0, reviewed=True)
    entries = len(s.history)
    assert not window.match_both()  # both accepted: nothing to do, and it says so
    assert "accepted" in window.statusBar().currentMessage() and len(s.history) == entries


def FakePlacement(name, pose, found):
    """What find_components returns: a placement of the engine's one Placement type."""
    from fluorogui.core.search.find import Placement

    return Placement(name, pose, found, [0.9, 0.8], float("nan"), [], "" if found else "no dark region", 0.1)


@pytest.fixture()
def fake_find(monkeypatch):
    """find_components replaced (the engine is being rewritten): it reports progress, may
    wait for a cancel, places the femoral component at the truth and not the tibial."""
    from fluorogui.core.cancel import Cancelled

    calls = {"wait": False, "seen_cancel": False, "truth": None}

    def find_components(images, views, meshes, near=None, progress=None, cancel=None):
        for k in range(5):
            if progress is not None:
                progress(k / 5, f"Searching orientations ({k + 1}/5)")
        while calls["wait"]:
            if cancel is not None and cancel():
                calls["seen_cancel"] = True
                raise Cancelled()
        t = calls["truth"]
        return {name: FakePlacement(name, t[name] if name == "femoral" else None, name == "femoral") for name in meshes}

    import fluorogui.workflow.finding as finding

    monkeypatch.setattr(finding, "find_components", find_components, raising=False)
    return calls


def test_find_implants_shows_progress_and_stores_only_confident_placements(window, demo, qtbot, fake_find):
    window.open_project(demo)
    s = window.controller.session
    fake_find["truth"] = {n: truth(s, 0, n) for n in s.components()}
    tibial_before = s.pose("tibial", 0)
    texts = []
    window.runner.progress.connect(lambda p: texts.append(window.matcher.progress.text()))
    with qtbot.waitSignal(window.runner.finished, timeout=60000):
        assert window.find_implants()
    assert texts and "%" in texts[-1]
    np.testing.assert_allclose(s.pose("femoral", 0), truth(s, 0, "femoral"))
    np.testing.assert_allclose(s.pose("tibial", 0), tibial_before)
    summary = window.matcher.summary.text()
    assert "femoral: found" in summary and "tibial: not placed (no dark region" in summary


def test_find_implants_can_be_cancelled(window, demo, qtbot, fake_find):
    window.open_project(demo)
    s = window.controller.session
    fake_find["wait"] = True
    entries = len(s.history)
    window.runner.progress.connect(lambda _p: window.actions_by_id["match.cancel"].trigger())  # Esc
    with qtbot.waitSignal(window.runner.cancelled, timeout=60000):
        assert window.find_implants()
    assert fake_find["seen_cancel"] and len(s.history) == entries
    assert "nothing changed" in window.matcher.summary.text()


def test_task_errors_reach_the_user_as_plain_sentences(window, demo, qtbot, dialogs, monkeypatch):
    from fluorogui.core.outlines.spline import OutlineError
    def broken(*args, **kwargs):
        raise OutlineError("outline crosses itself at point 5")

    import fluorogui.workflow.finding as finding

    monkeypatch.setattr(finding, "find_components", broken, raising=False)
    window.open_project(demo)
    with qtbot.waitSignal(window.runner.failed, timeout=60000):
        assert window.find_implants()
    message = dialogs["warning"][-1][2]
    assert message == "Outline crosses itself at point 5." and "Error" not in message


def test_a_project_another_program_holds_is_not_opened_behind_its_back(window, demo, dialogs, tmp_path,
                                                                        monkeypatch):
    holder = {"program": "fluorogui track", "pid": os.getppid(), "host": socket.gethostname(), "user": "x",
              "since": 0}
    lock_path(demo).write_text(json.dumps(holder))
    assert not window.open_project(demo, ask=False)  # the dialog's default: do not open
    text = dialogs["question"][-1][2]
    assert "is in use by fluorogui track" in text and "read-only" in text
    assert window.controller.path is None
    dialogs["answers"].append(QMessageBox.StandardButton.Open)
    assert window.open_project(demo, ask=False)
    assert window.controller.read_only and "(read-only)" in window.windowTitle()
    copy = tmp_path / "copy.fluoro"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(copy), ""))
    window.controller.session.set_pose("femoral", 0, np.ones(6))
    assert window.files.save()  # Save goes to Save As: never over the other program's file
    assert copy.exists() and json.loads(lock_path(demo).read_text())["program"] == "fluorogui track"
    assert not window.controller.read_only and "(read-only)" not in window.windowTitle()


def test_a_match_whose_outline_was_moved_for_the_rim_says_so(window, demo):
    from types import SimpleNamespace

    from fluorogui.core.status import Status
    from fluorogui.workflow import FrameResult

    window.open_project(demo)
    refined = SimpleNamespace(objective_mm=0.031, history=[0.5, 0.031], settings={"rim_refined": [False, True]})
    plain = SimpleNamespace(objective_mm=0.029, history=[0.4, 0.029], settings={"rim_refined": [False, False]})
    window.tasks.show_results([FrameResult(0, "femoral", np.zeros(6), Status.MATCHED, "", refined, seconds=1.0),
                          FrameResult(0, "tibial", np.zeros(6), Status.MATCHED, "", plain, seconds=1.0)])
    summary = window.matcher.summary.text()
    assert "femoral matched in 1.0 s, objective 0.031 mm (outline moved for the metal's soft rim in view 2)" in summary
    assert "tibial matched in 1.0 s, objective 0.029 mm." in summary and summary.count("soft rim") == 1


def _as_matched(session, frame):
    from fluorogui.core.records import PoseRecord

    for name in session.components():
        session.set_record(name, frame, PoseRecord(session.pose(name, frame), status="matched"), "Matched")


def test_find_implants_asks_before_replacing_matched_poses(window, demo, qtbot, dialogs, fake_find):
    """Nothing replaces a matched pose without saying so (issue 44, item 4)."""
    from PySide6.QtWidgets import QMessageBox

    window.open_project(demo)
    s = window.controller.session
    fake_find["truth"] = {n: truth(s, 0, n) for n in s.components()}
    _as_matched(s, 0)
    before = s.pose("femoral", 0)
    dialogs["answers"].append(QMessageBox.StandardButton.No)
    assert not window.find_implants()  # both matched, kept: nothing to search
    assert "Find them again and replace their poses?" in dialogs["question"][-1][2]
    assert "Kept the matched poses of frame 0" in window.statusBar().currentMessage()
    np.testing.assert_array_equal(s.pose("femoral", 0), before)
    dialogs["answers"].append(QMessageBox.StandardButton.Yes)
    with qtbot.waitSignal(window.runner.finished, timeout=60000):
        assert window.find_implants()
    assert s.pose_record("femoral", 0).status == "placed"  # replaced, as confirmed
    np.testing.assert_allclose(s.pose("femoral", 0), truth(s, 0, "femoral"))
