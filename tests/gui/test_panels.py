"""Pose editor, matcher panel and timeline: user input becomes signals, program input does not."""
import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import QPoint, Qt  # noqa: E402

from fluorogui.core.matching.problem import MatchSettings
from fluorogui.core.records import MatchRecord, PoseRecord  # noqa: E402
from fluorogui.core.status import Status
from fluorogui.gui.panels.matcher_panel import MatcherPanel, describe_pose  # noqa: E402
from fluorogui.gui.panels.pose_editor import PoseEditor  # noqa: E402
from fluorogui.gui.panels.timeline import STATE_COLOURS, Timeline, TimelineLegend  # noqa: E402
from fluorogui.workflow.session import FrameState  # noqa: E402


def test_pose_editor_emits_on_user_edits_only(qtbot):
    editor = PoseEditor()
    qtbot.addWidget(editor)
    edits = []
    editor.pose_edited.connect(edits.append)
    editor.set_pose([1, 2, 3, 4, 5, 6])
    assert edits == []
    np.testing.assert_allclose(editor.pose(), [1, 2, 3, 4, 5, 6])
    editor.rotation_step.setCurrentIndex(3)  # 5 degrees
    editor.nudge(4, -1)
    np.testing.assert_allclose(edits[-1], [1, 2, 3, 4, 0, 6])
    editor.spins[0].setFocus()
    qtbot.keyClick(editor.spins[0], Qt.Key.Key_Up)  # one 1 mm step
    np.testing.assert_allclose(edits[-1], [2, 2, 3, 4, 0, 6])


def test_pose_editor_shows_the_match_uncertainty(qtbot):
    editor = PoseEditor()
    qtbot.addWidget(editor)
    editor.set_uncertainty([0.0123, 0.2, 1.5, 0.04, None, float("inf")])
    assert [label.text() for label in editor.sd_labels] == ["± 0.012", "± 0.200", "± 1.500", "± 0.040", "± ?", "± ?"]
    assert editor.body_sd.isHidden()  # a match from before the body's SDs were kept
    # the real femur near gamma 78 deg: alpha and beta trade (about 1 deg each), its own turns do not
    editor.set_uncertainty([0.063, 0.11, 0.037, 0.996, 1.008, 0.109], [0.062, 0.121, 0.041, 0.067, 0.208, None])
    assert not editor.body_sd.isHidden()
    assert editor.body_sd.text() == "Turns about the model's own x, y, z axes: ± 0.067, 0.208, ?°"
    editor.set_uncertainty(None, [0.1] * 6)  # a pose placed by hand: nothing to show
    assert all(label.text() == "" for label in editor.sd_labels) and editor.body_sd.isHidden()


def test_matcher_panel_settings_and_buttons(qtbot):
    panel = MatcherPanel()
    qtbot.addWidget(panel)
    assert panel.settings().method == "fast" and panel.settings().model_points == 15000
    assert not panel.density.isEnabled()  # the point cloud is the paper method's alone
    with qtbot.waitSignal(panel.settings_edited):
        panel.method.setCurrentIndex(1)
    assert panel.settings().method == "paper" and panel.settings().outline_points == 60
    assert panel.density.isEnabled()
    panel.set_running(True)
    assert not panel.density.isEnabled()
    panel.set_running(False)
    assert panel.density.isEnabled()
    base = MatchSettings(max_calls=123)
    assert panel.settings(base).max_calls == 123  # the session's other settings are kept
    with qtbot.assertNotEmitted(panel.settings_edited):
        panel.set_settings(MatchSettings(method="fast", model_points=3500))
    assert panel.settings().method == "fast" and panel.settings().model_points == 3500
    assert not panel.density.isEnabled()
    for button, signal in ((panel.run_button, panel.run_requested), (panel.run_both_button, panel.run_both_requested),
                           (panel.track_button, panel.track_requested),
                           (panel.track_both_button, panel.track_both_requested)):
        with qtbot.waitSignal(signal):
            qtbot.mouseClick(button, Qt.MouseButton.LeftButton)
    panel.set_running(True)
    assert not panel.run_button.isEnabled() and not panel.track_both_button.isEnabled()
    assert panel.cancel_button.isEnabled()
    with qtbot.waitSignal(panel.cancel_requested):
        qtbot.mouseClick(panel.cancel_button, Qt.MouseButton.LeftButton)
    panel.show_live(12, 0.5, [2.0, 1.0, 0.5])
    assert panel.plot.values == [2.0, 1.0, 0.5] and "call 12" in panel.status.text()
    panel.show_batch(2, 8, 10.0)
    assert "about 30 s left" in panel.progress.text()  # the average so far (5 s a frame), six to go
    panel.set_running(False)
    assert panel.run_button.isEnabled() and not panel.progress.isVisible()


def test_pose_status_in_plain_words():
    match = MatchRecord(0.2, [0.1, 0.1], 30, 0.5, True, "fast")
    assert describe_pose("femoral", None)[0] == "femoral: not placed or matched in this frame"
    text, level = describe_pose("tibial", PoseRecord(np.zeros(6), match, status=Status.MATCHED))
    assert text == "tibial: matched, 0.200 mm (30 calls, 0.5 s)" and level == "ok"
    reason = "view 1: the tibial outline could not be traced, it crosses itself — edit it or re-run Find implants"
    text, level = describe_pose("tibial", PoseRecord(np.zeros(6), match, status=Status.NEEDS_REVIEW, reason=reason))
    assert text.startswith("tibial: needs review — " + reason) and level == "bad"
    text, level = describe_pose("tibial", PoseRecord(np.zeros(6), None, status=Status.FAILED, reason=reason))
    assert text == "tibial: failed — " + reason and level == "bad"
    text, level = describe_pose("tibial", PoseRecord(np.zeros(6), match, reviewed=True, status=Status.NEEDS_REVIEW,
                                                     reason="too far"))
    assert text.startswith("tibial: accepted") and "flagged: too far" in text and level == "ok"
    assert "Error" not in text and "placed" in describe_pose("femoral", PoseRecord(np.zeros(6)))[0]


def test_timeline_click_and_keys_select_frames(qtbot):
    timeline = Timeline()
    qtbot.addWidget(timeline)
    timeline.resize(400, 34)
    timeline.set_frames([0, 10, 20, 30], [FrameState.EMPTY, FrameState.OUTLINED, FrameState.MATCHED,
                                          FrameState.REVIEWED])
    with qtbot.waitSignal(timeline.frame_selected) as blocker:
        qtbot.mouseClick(timeline, Qt.MouseButton.LeftButton, pos=QPoint(360, 17))
    assert blocker.args == [30]  # frame numbers, not positions
    timeline.set_current(10)
    assert timeline.current_frame == 10
    with qtbot.waitSignal(timeline.frame_selected) as blocker:
        qtbot.keyClick(timeline, Qt.Key.Key_Right)
    assert blocker.args == [20]
    image = timeline.grab().toImage()
    assert image.pixelColor(380, 17) != image.pixelColor(20, 17)  # reviewed vs empty colours


def test_needs_review_has_its_own_colour_and_legend(qtbot):
    timeline = Timeline()
    qtbot.addWidget(timeline)
    timeline.resize(400, 34)
    timeline.set_frames([3, 4], [FrameState.MATCHED, FrameState.MATCHED])
    timeline.set_state(4, FrameState.NEEDS_REVIEW)
    timeline.set_note(4, "tibial: needs review — view 2: too far")
    assert timeline.state(4) == FrameState.NEEDS_REVIEW and "too far" in timeline.notes[4]
    colours = {c.rgb() for c in STATE_COLOURS.values()}
    assert len(colours) == len(STATE_COLOURS)  # every state its own colour
    image = timeline.grab().toImage()
    centre = timeline.cell_rect(4).center()
    assert image.pixelColor(int(centre.x()) + 30, int(centre.y())) == STATE_COLOURS[FrameState.NEEDS_REVIEW]
    assert "needs review (red)" in timeline.toolTip()
    legend = TimelineLegend()
    qtbot.addWidget(legend)
    assert "needs review" in legend.toolTip()
