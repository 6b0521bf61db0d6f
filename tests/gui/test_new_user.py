"""What a new user met in the desktop app (issue 44): Redo from the keyboard on every
platform's keys, the status bar after an undo, a new session shown whole, the Matcher
dock's buttons staying put through a task, and the outline tools saying what to do first
where there is no outline."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import Qt  # noqa: E402
from PySide6.QtGui import QKeySequence  # noqa: E402
from PySide6.QtTest import QTest  # noqa: E402
from PySide6.QtWidgets import QApplication  # noqa: E402

from fluorogui.gui.panels.image_items import Tool  # noqa: E402
from fluorogui.io.importer import import_folder  # noqa: E402

#: Redo's keys: the guides' Ctrl+Shift+Z, Ctrl+Y (Windows users' habit) and the platform's own
REDO_KEYS = ["Ctrl+Shift+Z", "Ctrl+Y"]

REDO_ON_X11 = """
import json, sys
from PySide6.QtCore import QSettings, Qt
from PySide6.QtGui import QKeySequence
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QApplication
from fluorogui.gui.main_window import MainWindow
from fluorogui.workflow.session.history import Command
app = QApplication([])
window = MainWindow(settings=QSettings(sys.argv[1], QSettings.Format.IniFormat), with_3d=False)
window.show()
window.activateWindow()
for _ in range(300):
    if QApplication.activeWindow() is window:
        break
    QTest.qWait(10)
history, state = window.controller.session.history, {}
keys = sys.argv[2:] + [k.toString() for k in QKeySequence.keyBindings(QKeySequence.StandardKey.Redo)]
redone = {}
for text in dict.fromkeys(keys):
    history.push(Command("Edit", "x", 0, 1, lambda key, value: state.__setitem__(key, value)))
    QTest.keyClick(window.windowHandle(), Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier)
    undone = state["x"] == 0
    combo = QKeySequence(text)[0]
    QTest.keyClick(window.windowHandle(), combo.key(), combo.keyboardModifiers())
    redone[text] = [undone, state["x"] == 1]
print(json.dumps({"platform": app.platformName(), "redone": redone}))
history.set_clean()
window.close()
"""


def _active(window, qtbot):
    """Show the window and make it the active one (shortcuts reach the active window only);
    returns its QWindow, where key events are matched against shortcuts."""
    window.show()
    window.activateWindow()
    qtbot.waitActive(window)
    window.panels[0].setFocus()
    handle = window.windowHandle()
    qtbot.waitUntil(lambda: QApplication.focusWindow() is handle)
    return handle


def _press(handle, text: str) -> None:
    combo = QKeySequence(text)[0]
    QTest.keyClick(handle, combo.key(), combo.keyboardModifiers())


def test_redo_answers_the_guides_keys_and_the_platforms(window, demo, qtbot):
    window.open_project(demo)
    handle = _active(window, qtbot)
    s, name = window.session, window.controller.component
    start = s.pose(name, 0)
    keys = dict.fromkeys(REDO_KEYS + [k.toString() for k in QKeySequence.keyBindings(QKeySequence.StandardKey.Redo)])
    for i, keys_text in enumerate(keys, start=1):
        moved = start + np.array([i, 0, 0, 0, 0, 0.0])
        s.set_pose(name, 0, moved, text=f"Move {i}")
        _press(handle, "Ctrl+Z")
        np.testing.assert_allclose(s.pose(name, 0), moved - [1, 0, 0, 0, 0, 0.0], err_msg="undo")
        _press(handle, keys_text)
        np.testing.assert_allclose(s.pose(name, 0), moved, err_msg=f"redo with {keys_text}")
    shortcuts = [k.toString() for k in window.edit.redo_action.shortcuts()]
    assert len(shortcuts) == len(set(shortcuts))  # a key bound twice is ambiguous: Qt ignores it


@pytest.mark.skipif(not os.environ.get("DISPLAY"), reason="needs an X display (run under xvfb-run)")
@pytest.mark.slow
def test_redo_from_the_keyboard_on_x11(tmp_path):
    """On X11 the platform's Redo is Ctrl+Shift+Z itself (offscreen gives Windows' keys)."""
    env = dict(os.environ, QT_QPA_PLATFORM="xcb", FLUOROGUI_DATA_DIR=str(tmp_path / "appdata"))
    run = subprocess.run([sys.executable, "-c", REDO_ON_X11, str(tmp_path / "settings.ini"), *REDO_KEYS],
                         env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    result = json.loads(run.stdout.strip().splitlines()[-1])
    assert result["platform"] == "xcb"
    assert set(REDO_KEYS) <= set(result["redone"])
    assert all(undone and redone for undone, redone in result["redone"].values()), result["redone"]


@pytest.mark.slow
def test_after_undoing_a_match_the_status_bar_says_so(window, demo, qtbot):
    window.open_project(demo)
    handle = _active(window, qtbot)
    name = window.controller.component
    with qtbot.waitSignal(window.runner.finished, timeout=120000):
        assert window.run_match()
    status = window.statusBar()
    assert f"{name} matched" in status.currentMessage() and "Ctrl+Return accepts" in status.currentMessage()
    assert window.matcher.summary.isVisibleTo(window)
    _press(handle, "Ctrl+Z")
    assert window.session.pose_record(name, 0).status.value == "placed"
    assert status.currentMessage() == f"Undone: Match {name} in frame 0 (Ctrl+Shift+Z redoes it)"
    assert not window.matcher.summary.isVisibleTo(window)  # the task's account is put away
    assert "placed, not matched" in window.matcher.status.text()  # what holds now
    _press(handle, "Ctrl+Shift+Z")
    assert window.session.pose_record(name, 0).status.value == "matched"
    assert status.currentMessage() == f"Redone: Match {name} in frame 0 (Ctrl+Z undoes it)"


def test_a_new_session_shows_its_images_whole(window, demo, qtbot):
    window.open_project(demo)
    window.resize(1100, 700)
    window.show()
    qtbot.waitExposed(window)
    panel = window.panels[0]
    panel.fit()
    fitted = panel.scale_factor()
    panel.zoom_at(4.0, panel.mapFromScene(100.0, 100.0))  # zoomed in on a corner of the demo
    assert panel.scale_factor() == pytest.approx(4 * fitted)
    window.edit.set_tool(Tool.ERASE)  # and some edges erased there
    start, end = panel.mapFromScene(100.0, 100.0), panel.mapFromScene(110.0, 104.0)
    qtbot.mousePress(panel.viewport(), Qt.MouseButton.LeftButton, pos=start)
    qtbot.mouseMove(panel.viewport(), end)
    qtbot.mouseRelease(panel.viewport(), Qt.MouseButton.LeftButton, pos=end)
    assert panel.erased_mask() is not None and panel.erased_mask().any()
    window.controller.set_project(import_folder(demo.parent), None)  # File → New session's last step
    assert panel.image() is not None and panel.image().shape == (512, 512)  # the same size as the demo's
    assert panel.scale_factor() == pytest.approx(fitted)  # shown whole
    centre = panel.mapFromScene(255.5, 255.5)
    assert abs(centre.x() - panel.viewport().width() / 2) <= 2 and abs(centre.y() - panel.viewport().height() / 2) <= 2
    assert panel.erased_mask() is None  # the demo's erased edges are not this session's


def _buttons_at(window):
    m = window.matcher
    return [b.mapTo(window, b.rect().topLeft()) for b in (m.run_button, m.place_button, m.track_button)]


def _settled(window, qtbot):
    """The buttons' places once the window's layout has settled (a loaded machine lays a
    newly shown window out in more than one pass)."""
    places = None
    for _ in range(40):
        qtbot.wait(50)
        now = _buttons_at(window)
        if now == places:
            break
        places = now
    return places


def test_the_matcher_buttons_stay_put_through_a_find(window, demo, qtbot):
    window.open_project(demo)
    window.resize(1100, 460)  # short: the Matcher dock scrolls, as on a 1280×720 screen with the 3D scene
    _active(window, qtbot)
    scroll = window.matcher_dock.widget().verticalScrollBar()
    before = _settled(window, qtbot)
    assert scroll.maximum() > 0 and scroll.value() == 0
    with qtbot.waitSignal(window.runner.finished, timeout=120000):
        qtbot.mouseClick(window.matcher.place_button, Qt.MouseButton.LeftButton)
        assert window.runner.is_running() and _buttons_at(window) == before
        assert window.matcher.cancel_button.hasFocus()  # not the next in the tab chain: Space cancels
    assert "Find implants in frame 0" in window.matcher.summary.text()
    assert scroll.value() == 0 and _buttons_at(window) == before
    assert window.matcher.place_button.hasFocus()  # back where it was
    with qtbot.waitSignal(window.runner.cancelled, timeout=120000):  # and when the find is cancelled
        qtbot.mouseClick(window.matcher.place_button, Qt.MouseButton.LeftButton)
        qtbot.mouseClick(window.matcher.cancel_button, Qt.MouseButton.LeftButton)
    assert scroll.value() == 0 and _buttons_at(window) == before


@pytest.mark.parametrize("tool", [Tool.MOVE, Tool.DELETE, Tool.LASSO, Tool.CLOSE_GAP])
def test_an_outline_tool_with_no_outline_says_what_to_do_first(window, demo, qtbot, tool):
    window.open_project(demo)  # the demo's models are placed; no outline yet
    window.show()
    qtbot.waitExposed(window)
    c, s = window.controller, window.session
    panel = window.panels[1]
    model = panel.model_outline(c.component)  # the line the user sees over the implant
    assert s.outline_points(c.outline_key(1)) is None and model is not None
    window.edit.set_tool(tool)
    qtbot.mouseClick(panel.viewport(), Qt.MouseButton.LeftButton, pos=panel.mapFromScene(*model[0]))
    message = window.statusBar().currentMessage()
    assert message.startswith(f"{window.edit.tool_actions[tool].text()}: there is no {c.component} outline in view 2")
    assert "Match (F5)" in message and "Pick contour (P)" in message
    assert s.outline_points(c.outline_key(1)) is None and not s.history.can_undo()  # nothing changed
    square = np.array([[100, 100], [200, 100], [200, 200], [100, 200.0]])
    s.set_outline(c.outline_key(1), square, reviewed=False)  # with an outline the tool edits it
    window.statusBar().clearMessage()
    qtbot.mouseClick(panel.viewport(), Qt.MouseButton.LeftButton, pos=panel.mapFromScene(200.0, 200.0))
    assert "there is no" not in window.statusBar().currentMessage()
