"""The main window on a small generated demo session: open, match in the worker, cancel,
edit and undo, keep spin boxes, poses and overlays in step, save and reopen, refuse bad files."""
import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import QSettings, Qt  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from fluorogui.core.projection.pose import pose_error  # noqa: E402
from fluorogui.gui.main_window import MainWindow  # noqa: E402
from fluorogui.gui.panels.image_panel import Tool  # noqa: E402
from fluorogui.workflow.session import FrameState  # noqa: E402


def test_opening_a_session_shows_images_outlines_and_frames(window, demo):
    assert window.open_project(demo)
    c = window.controller
    assert "demo.fluoro" in window.windowTitle()
    assert all(panel.image() is not None and panel.image().shape == (512, 512) for panel in window.panels)
    assert window.timeline.frames == [0, 1, 2]
    assert window.model.component_combo.count() == 2
    first = c.components()[0]
    # the projected model outline is drawn in both panels
    assert all(panel.model_outline(first) is not None and len(panel.model_outline(first)) > 20
               for panel in window.panels)
    window.review.step_frame(1)
    assert c.frame == 1 and window.timeline.current_frame == 1


@pytest.mark.slow
def test_match_runs_in_the_worker_and_lands_on_the_truth(window, demo, qtbot):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    name = c.components()[1]  # the tibial component
    c.set_component(name)
    updates = []
    window.runner.progress.connect(updates.append)
    with qtbot.waitSignal(window.runner.finished, timeout=120000):
        assert window.run_match()
    truth = np.array(c.project.settings["demo_truth"]["0"][name])
    record = s.pose_record(name, 0)
    assert record.match is not None and record.match.converged and record.status == "matched"
    err = pose_error(record.pose, truth)
    assert np.abs(err[:3]).max() < 0.1 and np.abs(err[3:]).max() < 0.2
    assert all(s.outline_record(c.outline_key(v, name)) is not None for v in range(2))  # automatic outlines
    assert f"{name}: matched" in window.matcher.status.text()
    assert s.pose_record(c.components()[0], 0).match is None  # only the active component
    np.testing.assert_allclose(window.pose_editor.pose(), record.pose, atol=1e-3)
    # accept, then undo the acceptance and the match in two steps
    window.review.accept_pose()
    assert s.pose_record(name, 0).reviewed
    window.edit.undo_action.trigger()
    assert not s.pose_record(name, 0).reviewed
    window.edit.undo_action.trigger()
    assert s.pose_record(name, 0).match is None  # back to the demo's rough start


def test_cancel_leaves_the_previous_pose(window, demo, qtbot):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    name = c.components()[0]
    before = s.pose(name, 0)
    entries = len(s.history)
    window.matcher.method.setCurrentIndex(1)  # the paper method: hundreds of calls
    seen = []
    for signal in ("finished", "cancelled", "failed"):
        getattr(window.runner, signal).connect(lambda *a, s=signal: seen.append(s))
    window.runner.progress.connect(lambda _p: window.runner.cancel())
    with qtbot.waitSignal(window.runner.cancelled, timeout=120000):
        window.run_match()
    assert seen == ["cancelled"]
    np.testing.assert_allclose(s.pose(name, 0), before)
    assert s.pose_record(name, 0).match is None and len(s.history) == entries and not c.dirty
    assert "Cancelled" in window.matcher.status.text()
    assert window.matcher.run_button.isEnabled()


def test_spin_boxes_pose_and_overlay_stay_in_step(window, demo):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    name = c.component
    panel = window.panels[0]
    before_overlay = panel.model_outline(name).copy()
    window.pose_editor.spins[0].setValue(window.pose_editor.spins[0].value() + 5.0)  # user edit
    assert s.pose(name, 0)[0] == pytest.approx(window.pose_editor.pose()[0])
    after_overlay = panel.model_outline(name)
    assert not np.array_equal(before_overlay.shape, after_overlay.shape) or np.abs(after_overlay.mean(0)
                                                                                   - before_overlay.mean(0)).max() > 1
    target = s.pose(name, 0) + np.array([0, 0, 0, 0, 7.0, 0])
    s.set_pose(name, 0, target)
    np.testing.assert_allclose(window.pose_editor.pose(), target, atol=1e-3)
    window.pose_editor.nudge(2, 1)  # a keyboard nudge of 1 mm
    assert s.pose(name, 0)[2] == pytest.approx(target[2] + 1.0)


def test_outline_edit_in_a_panel_is_stored_and_undone(window, demo, qtbot):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    name = c.component
    key = c.outline_key(0)
    square = np.array([[100, 100], [200, 100], [200, 200], [100, 200.0]])
    s.set_outline(key, square, reviewed=False)
    np.testing.assert_allclose(window.panels[0].outline(name), square)
    panel = window.panels[0]
    panel.set_tool(Tool.DELETE)
    qtbot.mouseClick(panel.viewport(), Qt.MouseButton.LeftButton, pos=panel.mapFromScene(200.0, 200.0))
    assert len(s.outline_points(key)) == 3  # the panel's edit reached the session
    assert s.outline_record(key).reviewed  # a user's edit: matching uses it as it is
    assert len(panel.outline(name)) == 3
    assert window.edit.undo_action.text().endswith("Delete point")
    window.edit.undo_action.trigger()
    np.testing.assert_allclose(s.outline_points(key), square)
    np.testing.assert_allclose(panel.outline(name), square)
    window.review.step_frame(1)  # undo / redo still apply to frame 0's outline
    window.edit.redo_action.trigger()
    assert len(s.outline_points(key)) == 3 and panel.outline(name) is None


def test_point_and_click_places_the_model(window, demo):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    name = c.component
    truth = np.array(c.project.settings["demo_truth"]["0"][name])
    from fluorogui.core.projection.pose import rotation_matrix

    centre = rotation_matrix(*truth[3:]) @ s.mesh(name).centroid + truth[:3]
    window.edit.set_tool(Tool.PLACE)
    for view, panel in enumerate(window.panels):
        u, v = c.project.views[view].project(centre[None])[0]
        panel.point_clicked.emit(view, float(u), float(v))
    pose = s.pose(name, 0)
    placed = rotation_matrix(*pose[3:]) @ s.mesh(name).centroid + pose[:3]
    assert np.linalg.norm(placed - centre) < 1e-3 and window.model.last_place_miss < 1e-3
    assert "miss" in window.statusBar().currentMessage()


def test_save_then_reopen_gives_the_same_session(window, demo, tmp_path, qtbot):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    s.set_pose(c.component, 0, s.pose(c.component, 0) + 1.0)
    s.set_outline(c.outline_key(1), np.array([[10, 10], [60, 10], [60, 60], [10, 60.0]]))
    assert window.isWindowModified()
    target = tmp_path / "saved.fluoro"
    assert window.files.save_to(target)
    assert not window.isWindowModified() and "saved.fluoro" in window.windowTitle()
    other = MainWindow(settings=QSettings(str(tmp_path / "other.ini"), QSettings.Format.IniFormat), with_3d=False)
    qtbot.addWidget(other)
    assert other.open_project(target)
    assert other.controller.project == c.project
    assert str(target.resolve()) in window.files.recent_files()
    other.controller.close()


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
    c, s = window.controller, window.controller.session
    s.set_pose(c.component, 0, s.pose(c.component, 0) + 1.0)
    dialogs["answers"].append(QMessageBox.StandardButton.Cancel)
    window.show()
    window.close()
    assert window.isVisible() and len(dialogs["question"]) == 1
    dialogs["answers"].append(QMessageBox.StandardButton.Discard)
    window.close()
    assert not window.isVisible()
    from fluorogui.io.project.lock import lock_path

    assert not lock_path(demo).exists()  # closing lets go of the file


def test_autosave_and_recovery(window, demo, tmp_path, qtbot, dialogs):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    s.set_pose(c.component, 0, s.pose(c.component, 0) + 2.0)
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
    other.controller.session.history.set_clean()
    other.controller.close()


def test_timeline_shows_frame_states(window, demo, qtbot):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    assert window.timeline.states == s.frame_states()
    s.set_outline(c.outline_key(0), np.array([[10, 10], [60, 10], [60, 60], [10, 60.0]]))
    assert window.timeline.states[0] == FrameState.OUTLINED


def test_dropping_a_project_opens_it(window, demo):
    window.open_paths([demo])
    assert window.controller.path == demo


@pytest.mark.slow
def test_track_following_frames_matches_every_frame(window, demo, qtbot):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    name = c.components()[1]
    c.set_component(name)
    shown = []
    window.frame_shown.connect(shown.append)
    with qtbot.waitSignal(window.runner.finished, timeout=300000):
        assert window.tasks.track_frames()  # frame 0 is not matched yet: tracking starts there
    for frame in c.frames:
        record = s.pose_record(name, frame)
        assert record is not None and record.status == "matched" and record.match.converged
        truth = np.array(c.project.settings["demo_truth"][str(frame)][name])
        assert np.abs(pose_error(record.pose, truth)).max() < 0.2
        assert s.pose_record(c.components()[0], frame) is None or frame == 0  # only the active component
    # the view followed the tracked frames to the last (at most one per event-loop pass)
    assert shown and shown[-1] == 2 and shown == sorted(shown) and c.frame == 2
    summary = window.matcher.summary.text()
    assert "3 matched, 0 need review, 0 failed" in summary and "3 of 3 frames" in summary
    assert summary in window.statusBar().currentMessage()


def test_dropped_folder_opens_the_import_dialog_filled(window, demo, monkeypatch):
    from fluorogui.gui.dialogs.import_dialog import ImportDialog

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


def test_the_menus_actions_ask_as_their_methods_do(window, demo, dialogs, monkeypatch):
    """A menu action passes Qt's ``checked`` to its slot: it must not land in a parameter
    (the demo action skipped the unsaved-changes question; Import poses… crashed)."""
    from PySide6.QtWidgets import QFileDialog

    window.open_project(demo)
    window.session.set_pose("femoral", window.controller.frame, np.ones(6))  # an unsaved change
    dialogs["answers"].append(QMessageBox.StandardButton.Cancel)
    window.actions_by_id["file.demo"].trigger()
    assert dialogs["question"] and window.controller.path == demo and window.controller.dirty
    asked = []
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (asked.append(a[1]), ("", ""))[1])
    window.actions_by_id["file.import_poses"].trigger()
    assert asked == ["Import poses"]
