"""The main window's extension points: a panel and its action declared in one place (a
``PanelSpec`` with its ``ActionSpec``, added to the window's layout) appear as a dock, a
View-menu entry, a menu action with its shortcut in the F1 list, and the action works;
whether an action is enabled follows the window's context."""
import threading

import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import QObject, QSettings, Qt  # noqa: E402
from PySide6.QtGui import QKeySequence  # noqa: E402
from PySide6.QtWidgets import QLabel, QMainWindow  # noqa: E402

from fluorogui.core.records import PoseRecord  # noqa: E402
from fluorogui.gui.layout.build import build_actions, key_sequences  # noqa: E402
from fluorogui.gui.layout.specs import ActionSpec, Context, PanelSpec, Place  # noqa: E402
from fluorogui.gui.layout.window import WINDOW  # noqa: E402
from fluorogui.gui.main_window import MainWindow  # noqa: E402


class FrameCounter(QObject):
    """The toy panel's presenter: given the controller and its label, nothing else."""

    def __init__(self, controller, label: QLabel) -> None:
        super().__init__(label)
        self.controller = controller
        self.label = label

    def count(self) -> None:
        self.label.setText(f"{len(self.controller.frames)} frames")


COUNT = ActionSpec("view.count_frames", "&Count frames", lambda p: p.toy.count(), (Place("view", "1_images", 3),),
                   shortcut="Ctrl+Alt+T", tip="Count the session's frames (Ctrl+Alt+T)")
TOY = PanelSpec("toy", "Frame count", "toyDock", Qt.DockWidgetArea.RightDockWidgetArea, lambda parts: QLabel("–"),
                lambda parts, label: FrameCounter(parts.controller, label), tab_with="kinematics", actions=(COUNT,))


@pytest.fixture()
def toy_window(qtbot, tmp_path, monkeypatch, dialogs):
    monkeypatch.setenv("FLUOROGUI_DATA_DIR", str(tmp_path / "appdata"))
    window = MainWindow(settings=QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat),
                        with_3d=False, layout=WINDOW.adding(panels=[TOY]))
    qtbot.addWidget(window)
    yield window
    window.controller.session.history.set_clean()
    window.controller.close()


def _menu(window, title):
    return next(a.menu() for a in window.menuBar().actions() if a.text() == title)


def test_a_panel_and_an_action_declared_once_are_in_the_window(toy_window, demo):
    window = toy_window
    dock = window.docks["toy"]
    assert dock.objectName() == "toyDock" and dock.windowTitle() == "Frame count"
    assert window.dockWidgetArea(dock) == Qt.DockWidgetArea.RightDockWidgetArea
    assert window.docks["kinematics"] in window.tabifiedDockWidgets(dock)  # a tab beside Kinematics
    label = window.widgets.toy
    assert dock.widget() is label and isinstance(window.presenters.toy, FrameCounter)
    # the View menu: the action in its group (after Show edges), the panel's check box with the others
    texts = [a.text() if not a.isSeparator() else "---" for a in _menu(window, "&View").actions()]
    assert texts[:4] == ["&Fit images", "Show &edges", "&Count frames", "---"]
    panels = texts[texts.index("---") + 1:texts.index("---", 4)]
    assert panels == ["Pose", "Session", "Kinematics", "Frames", "Frame count", "Matcher"]  # declared last
    toggle = next(a for a in _menu(window, "&View").actions() if a.text() == "Frame count")
    window.show()
    toggle.trigger()
    assert not dock.isVisible()
    # its shortcut works window-wide, so Help lists it
    assert ("Count frames", "Ctrl+Alt+T") in window.help.shortcut_rows()
    assert window.actions_by_id["view.count_frames"].shortcut() == QKeySequence("Ctrl+Alt+T")
    # and the action does what it says, through its presenter
    window.open_project(demo)
    window.actions_by_id["view.count_frames"].trigger()
    assert label.text() == "3 frames"


def test_the_window_without_the_toy_is_as_declared(window):
    assert "toy" not in window.docks and "view.count_frames" not in window.actions_by_id
    assert [d.objectName() for d in window.docks.values()] == [
        "matcherDock", "poseDock", "sessionDock", "kneeDock", "timelineDock"]  # no 3D scene in this window
    assert [a.text() for a in window.menuBar().actions()] == ["&File", "&Edit", "&View", "&Model", "M&atch", "&Help"]


def test_two_actions_with_one_id_are_refused(qtbot, tmp_path):
    with pytest.raises(ValueError, match="file.open"):
        MainWindow(settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat), with_3d=False,
                   layout=WINDOW.adding(actions=[ActionSpec("file.open", "Open again", lambda p: None)]))


def test_enabled_when_follows_the_context(qtbot):
    window = QMainWindow()
    qtbot.addWidget(window)
    context = Context()
    specs = [ActionSpec("a.run", "Run", lambda p: None, enabled_when=("!running",)),
             ActionSpec("a.cancel", "Cancel", lambda p: None, enabled_when=("running",)),
             ActionSpec("a.accept", "Accept", lambda p: None, enabled_when=("!running", "acceptable")),
             ActionSpec("a.free", "Free", lambda p: None)]
    actions = build_actions(window, specs, None, context)
    enabled = lambda: [actions[s.id].isEnabled() for s in specs]
    assert enabled() == [True, False, False, True]
    context.set(acceptable=True)
    assert enabled() == [True, False, True, True]
    context.set(running=True)
    assert enabled() == [False, True, False, True]
    actions["a.free"].setEnabled(False)  # an action without enabled-when is its presenter's
    context.set(running=False)
    assert enabled() == [True, False, True, False]


def test_a_tuple_of_keys_binds_each_once():
    keys = [k.toString(QKeySequence.SequenceFormat.PortableText)
            for k in key_sequences(("Ctrl+Z", QKeySequence.StandardKey.Undo))]
    assert keys[0] == "Ctrl+Z" and len(keys) == len(set(keys))
    assert [k.toString() for k in key_sequences("Ctrl+E")] == ["Ctrl+E"] and key_sequences(None) == []


def test_accept_is_greyed_out_without_a_session_and_while_a_task_runs(window, demo, qtbot):
    """Accept did nothing then (the Matcher panel's button was already greyed out); its
    action now says so too, by its enabled-when."""
    accept, unaccept = window.actions_by_id["match.accept"], window.actions_by_id["match.unaccept"]
    assert not accept.isEnabled() and not unaccept.isEnabled()  # no session
    window.open_project(demo)
    c, s = window.controller, window.session
    gate = threading.Event()
    assert window.runner.start(lambda reporter: gate.wait(10), "Waiting")  # a task: nothing may be accepted
    record = s.pose_record(c.component, c.frame)
    s.set_record(c.component, c.frame, PoseRecord(record.pose, None, status="matched"), "Matched by hand")
    assert not accept.isEnabled() and not window.matcher.accept_button.isEnabled()
    with qtbot.waitSignal(window.runner.finished, timeout=10000):
        gate.set()
    assert accept.isEnabled() and not unaccept.isEnabled() and window.matcher.accept_button.isEnabled()
