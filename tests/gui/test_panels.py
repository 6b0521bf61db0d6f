"""Pose editor, matcher panel and timeline: user input becomes signals, program input does not."""
import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import QPoint, Qt  # noqa: E402

from fluorogui.gui.controller import FrameState  # noqa: E402
from fluorogui.gui.matcher_panel import MatcherPanel  # noqa: E402
from fluorogui.gui.pose_editor import PoseEditor  # noqa: E402
from fluorogui.gui.timeline import Timeline  # noqa: E402


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


def test_matcher_panel_settings_and_buttons(qtbot):
    panel = MatcherPanel()
    qtbot.addWidget(panel)
    assert panel.settings().method == "fast" and panel.settings().model_points == 15000
    panel.method.setCurrentIndex(1)
    assert panel.settings().method == "paper" and panel.settings().outline_points == 60
    with qtbot.waitSignal(panel.run_requested):
        qtbot.mouseClick(panel.run_button, Qt.MouseButton.LeftButton)
    panel.set_running(True)
    assert not panel.run_button.isEnabled() and panel.cancel_button.isEnabled()
    with qtbot.waitSignal(panel.cancel_requested):
        qtbot.mouseClick(panel.cancel_button, Qt.MouseButton.LeftButton)
    panel.show_live(12, 0.5, [2.0, 1.0, 0.5])
    assert panel.plot.values == [2.0, 1.0, 0.5] and "call 12" in panel.status.text()
    panel.set_running(False)
    assert panel.run_button.isEnabled()


def test_timeline_click_and_keys_select_frames(qtbot):
    timeline = Timeline()
    qtbot.addWidget(timeline)
    timeline.resize(400, 34)
    timeline.set_frames([0, 10, 20, 30], [FrameState.EMPTY, FrameState.OUTLINED, FrameState.MATCHED,
                                          FrameState.REVIEWED])
    with qtbot.waitSignal(timeline.frame_selected) as blocker:
        qtbot.mouseClick(timeline, Qt.MouseButton.LeftButton, pos=QPoint(360, 17))
    assert blocker.args == [3]
    timeline.set_current(1)
    with qtbot.waitSignal(timeline.frame_selected) as blocker:
        qtbot.keyClick(timeline, Qt.Key.Key_Right)
    assert blocker.args == [2]
    image = timeline.grab().toImage()
    assert image.pixelColor(380, 17) != image.pixelColor(20, 17)  # reviewed vs empty colours
