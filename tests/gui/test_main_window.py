"""The main window on a small generated demo session: open, match in the worker, cancel,
edit and undo, keep spin boxes, poses and overlays in step, save and reopen, refuse bad files."""
import shutil

import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import QSettings, Qt  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from fluorogui.core.pose import pose_error  # noqa: E402
from fluorogui.gui.controller import FrameState  # noqa: E402
from fluorogui.gui.image_panel import Tool  # noqa: E402
from fluorogui.gui.main_window import MainWindow  # noqa: E402
from fluorogui.io.demo import build_demo_project  # noqa: E402


@pytest.fixture(scope="session")
def demo_source(tmp_path_factory):
    return build_demo_project(tmp_path_factory.mktemp("demo"), frames=3, image_size=512)


@pytest.fixture()
def demo(demo_source, tmp_path):
    target = tmp_path / "demo"
    shutil.copytree(demo_source.parent, target)
    return target / demo_source.name


@pytest.fixture()
def dialogs(monkeypatch):
    """Record message boxes instead of blocking; questions answer from ``answers``."""
    seen = {"warning": [], "question": [], "answers": []}

    def warning(*args, **kwargs):
        seen["warning"].append(args)
        return QMessageBox.StandardButton.Ok

    def question(*args, **kwargs):
        seen["question"].append(args)
        return seen["answers"].pop(0) if seen["answers"] else QMessageBox.StandardButton.Discard

    monkeypatch.setattr(QMessageBox, "warning", warning)
    monkeypatch.setattr(QMessageBox, "question", question)
    return seen


@pytest.fixture()
def window(qtbot, tmp_path, monkeypatch, dialogs):
    monkeypatch.setenv("FLUOROGUI_DATA_DIR", str(tmp_path / "appdata"))
    w = MainWindow(settings=QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat), with_3d=False)
    qtbot.addWidget(w)
    yield w
    w.runner.cancel()
    w.runner.wait()
    w.controller.undo_stack.setClean()


def test_opening_a_session_shows_images_outlines_and_frames(window, demo):
    assert window.open_project(demo)
    c = window.controller
    assert "demo.fluoro" in window.windowTitle()
    assert all(panel.image() is not None and panel.image().shape == (512, 512) for panel in window.panels)
    assert window.timeline.frames == [0, 1, 2]
    assert window.component_combo.count() == 2
    first = c.components()[0]
    # the projected model outline is drawn in both panels
    assert all(panel.model_outline(first) is not None and len(panel.model_outline(first)) > 20
               for panel in window.panels)
    window.step_frame(1)
    assert c.frame == 1 and window.timeline.current == 1


def test_match_runs_in_the_worker_and_lands_on_the_truth(window, demo, qtbot):
    window.open_project(demo)
    c = window.controller
    name = c.components()[1]  # the tibial component
    c.set_component(name)
    updates = []
    window.runner.progress.connect(updates.append)
    with qtbot.waitSignal(window.runner.finished, timeout=120000):
        assert window.run_match()
    truth = np.array(c.project.settings["demo_truth"]["0"][name])
    record = c.pose_record(name)
    assert record.match is not None and record.match.converged
    err = pose_error(record.pose, truth)
    assert np.abs(err[:3]).max() < 0.1 and np.abs(err[3:]).max() < 0.2
    assert all(c.outline_record(c.outline_key(v, name)) is not None for v in range(2))  # automatic outlines
    assert "converged" in window.matcher.status.text()
    np.testing.assert_allclose(window.pose_editor.pose(), record.pose, atol=1e-3)
    # accept, then undo the acceptance and the match in two steps
    window.accept_pose()
    assert c.pose_record(name).reviewed
    window.undo_action.trigger()
    assert not c.pose_record(name).reviewed
    window.undo_action.trigger()
    assert c.pose_record(name).match is None  # back to the demo's rough start


def test_cancel_leaves_the_previous_pose(window, demo, qtbot):
    window.open_project(demo)
    c = window.controller
    name = c.components()[0]
    before = c.pose(name)
    window.matcher.method.setCurrentIndex(1)  # the paper method: hundreds of calls
    seen = []
    for signal in ("finished", "cancelled", "failed"):
        getattr(window.runner, signal).connect(lambda *a, s=signal: seen.append(s))
    window.runner.progress.connect(lambda _p: window.runner.cancel())
    with qtbot.waitSignal(window.runner.cancelled, timeout=120000):
        window.run_match()
    assert seen == ["cancelled"]
    np.testing.assert_allclose(c.pose(name), before)
    assert c.pose_record(name).match is None
    assert "Cancelled" in window.matcher.status.text()
    assert window.matcher.run_button.isEnabled()


def test_spin_boxes_pose_and_overlay_stay_in_step(window, demo):
    window.open_project(demo)
    c = window.controller
    name = c.component
    panel = window.panels[0]
    before_overlay = panel.model_outline(name).copy()
    window.pose_editor.spins[0].setValue(window.pose_editor.spins[0].value() + 5.0)  # user edit
    assert c.pose(name)[0] == pytest.approx(window.pose_editor.pose()[0])
    after_overlay = panel.model_outline(name)
    assert not np.array_equal(before_overlay.shape, after_overlay.shape) or np.abs(after_overlay.mean(0)
                                                                                   - before_overlay.mean(0)).max() > 1
    target = c.pose(name) + np.array([0, 0, 0, 0, 7.0, 0])
    c.set_pose(name, target)
    np.testing.assert_allclose(window.pose_editor.pose(), target, atol=1e-3)
    window.pose_editor.nudge(2, 1)  # a keyboard nudge of 1 mm
    assert c.pose(name)[2] == pytest.approx(target[2] + 1.0)


def test_outline_edit_in_a_panel_is_stored_and_undone(window, demo, qtbot):
    window.open_project(demo)
    c = window.controller
    name = c.component
    key = c.outline_key(0)
    square = np.array([[100, 100], [200, 100], [200, 200], [100, 200.0]])
    c.set_outline(key, square)
    np.testing.assert_allclose(window.panels[0].outline(name), square)
    panel = window.panels[0]
    panel.set_tool(Tool.DELETE)
    qtbot.mouseClick(panel.viewport(), Qt.MouseButton.LeftButton, pos=panel.mapFromScene(200.0, 200.0))
    assert len(c.outline_points(key)) == 3  # the panel's edit reached the project
    window.undo_action.trigger()
    np.testing.assert_allclose(c.outline_points(key), square)
    window.redo_action.trigger()
    assert len(c.outline_points(key)) == 3


def test_point_and_click_places_the_model(window, demo):
    window.open_project(demo)
    c = window.controller
    name = c.component
    truth = np.array(c.project.settings["demo_truth"]["0"][name])
    from fluorogui.core.pose import rotation_matrix

    centre = rotation_matrix(*truth[3:]) @ c.mesh(name).centroid + truth[:3]
    window.set_tool(Tool.PLACE)
    for view, panel in enumerate(window.panels):
        u, v = c.project.views[view].project(centre[None])[0]
        panel.point_clicked.emit(view, float(u), float(v))
    pose = c.pose(name)
    placed = rotation_matrix(*pose[3:]) @ c.mesh(name).centroid + pose[:3]
    assert np.linalg.norm(placed - centre) < 1e-3 and window.last_place_miss < 1e-3
    assert "miss" in window.statusBar().currentMessage()


def test_save_then_reopen_gives_the_same_session(window, demo, tmp_path, qtbot):
    window.open_project(demo)
    c = window.controller
    c.set_pose(c.component, c.pose(c.component) + 1.0)
    c.set_outline(c.outline_key(1), np.array([[10, 10], [60, 10], [60, 60], [10, 60.0]]))
    assert window.isWindowModified()
    target = tmp_path / "saved.fluoro"
    assert window._save_to(target)
    assert not window.isWindowModified() and "saved.fluoro" in window.windowTitle()
    other = MainWindow(settings=QSettings(str(tmp_path / "other.ini"), QSettings.Format.IniFormat), with_3d=False)
    qtbot.addWidget(other)
    assert other.open_project(target)
    assert other.controller.project == c.project
    assert str(target.resolve()) in window.recent_files()


def test_a_bad_file_gives_a_dialog_and_keeps_the_open_session(window, demo, tmp_path, dialogs):
    window.open_project(demo)
    opened = window.controller.project
    bad = tmp_path / "broken.fluoro"
    bad.write_text('{"format": "fluorogui-project", "schema_version": 2, "views": [')
    assert not window.open_project(bad, ask=False)
    assert len(dialogs["warning"]) == 1 and "broken.fluoro" in dialogs["warning"][0][2]
    assert window.controller.project is opened
    newer = tmp_path / "newer.fluoro"
    newer.write_text('{"format": "fluorogui-project", "schema_version": 99}')
    assert not window.open_project(newer, ask=False)
    assert "newer.fluoro" in dialogs["warning"][1][2]


def test_close_asks_about_unsaved_changes(window, demo, dialogs):
    window.open_project(demo)
    c = window.controller
    c.set_pose(c.component, c.pose(c.component) + 1.0)
    dialogs["answers"].append(QMessageBox.StandardButton.Cancel)
    window.show()
    window.close()
    assert window.isVisible() and len(dialogs["question"]) == 1
    dialogs["answers"].append(QMessageBox.StandardButton.Discard)
    window.close()
    assert not window.isVisible()


def test_autosave_and_recovery(window, demo, tmp_path, qtbot, dialogs):
    window.open_project(demo)
    c = window.controller
    c.set_pose(c.component, c.pose(c.component) + 2.0)
    assert window.autosave()
    assert window.recovery_path().exists()
    expected = c.project
    # a new window (after a crash) offers the autosaved session
    other = MainWindow(settings=QSettings(str(tmp_path / "other.ini"), QSettings.Format.IniFormat), with_3d=False)
    qtbot.addWidget(other)
    dialogs["answers"].append(QMessageBox.StandardButton.Yes)
    assert other.offer_recovery()
    assert other.controller.project == expected
    assert other.controller.path == demo and other.controller.dirty
    other.controller.undo_stack.setClean()


def test_timeline_shows_frame_states(window, demo, qtbot):
    window.open_project(demo)
    c = window.controller
    assert window.timeline.states == [FrameState.EMPTY] * 3
    c.set_outline(c.outline_key(0), np.array([[10, 10], [60, 10], [60, 60], [10, 60.0]]))
    assert window.timeline.states[0] == FrameState.OUTLINED


def test_dropping_a_project_opens_it(window, demo):
    window.open_paths([demo])
    assert window.controller.path == demo


def test_track_following_frames_matches_every_frame(window, demo, qtbot):
    window.open_project(demo)
    c = window.controller
    name = c.components()[1]
    c.set_component(name)
    batches = []
    window.runner.progress.connect(batches.append)
    with qtbot.waitSignal(window.runner.finished, timeout=300000):
        assert window.track_frames()
    for frame in c.frames:
        record = c.pose_record(name, frame)
        assert record is not None and record.match is not None and record.match.converged
        truth = np.array(c.project.settings["demo_truth"][str(frame)][name])
        assert np.abs(pose_error(record.pose, truth)).max() < 0.2
    assert [b.done for b in batches if hasattr(b, "done")][-1] == len(c.frames)
    assert "3 frame" in window.statusBar().currentMessage()


def test_dropped_folder_opens_the_import_dialog_filled(window, demo, monkeypatch):
    from fluorogui.gui.import_dialog import ImportDialog

    shown = []

    def fake_exec(dialog):
        shown.append({k: e.text() for k, e in dialog.fields.items()})
        dialog.accept()
        return ImportDialog.DialogCode.Accepted if dialog.project is not None else ImportDialog.DialogCode.Rejected

    monkeypatch.setattr(ImportDialog, "exec", fake_exec)
    window.open_paths([demo.parent])
    assert shown and shown[0]["pairs_csv"].endswith("pairs.csv")
    assert len(window.controller.frames) == 3 and window.controller.path is None
    assert window.controller.dirty  # an import is unsaved work
