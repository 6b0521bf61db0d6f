"""The Kinematics dock, Export and Import poses in the main window on the demo: values follow
the frame, the side is a session edit, a click on the curves goes to that frame, exports
are written and imports land as placed poses."""
import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PySide6.QtWidgets import QDialog  # noqa: E402

from fluorogui.core.records import PoseRecord  # noqa: E402
from fluorogui.gui.dialogs.export_dialog import ExportDialog  # noqa: E402


def put_truth(session):
    for frame, by in session.project.settings["demo_truth"].items():
        for c, pose in by.items():
            session.project.poses[(int(frame), c)] = PoseRecord(np.asarray(pose, float))


def test_dock_shows_the_current_frame_and_follows_clicks(window, demo, qtbot):
    window.open_project(demo)
    session = window.session
    put_truth(session)
    window.presenters.kinematics.refresh_knee()
    panel = window.knee_panel
    row = session.knee_at(window.controller.frame)
    assert panel.value_labels[0].text() == f"{row.values.flexion_deg:.2f}"
    assert "Needs review: femoral placed by hand, not matched" in panel.status.text()  # no match record
    window.controller.set_frame(2)
    assert panel.value_labels[0].text() == f"{session.knee_at(2).values.flexion_deg:.2f}"
    qtbot.waitUntil(lambda: len(panel.axes) == 7, timeout=3000)
    # a click near frame 1 on the flexion curve goes there
    with qtbot.waitSignal(panel.frame_selected):
        panel.frame_selected.emit(panel.frame_near(1.2, None, "flexion_deg"))
    assert window.controller.frame == 1
    panel.against.setCurrentIndex(1)  # against flexion: the nearest flexion wins
    flexions = {r.frame: r.values.flexion_deg for r in panel.rows}
    assert panel.frame_near(flexions[2] + 0.1, None, "varus_deg") == 2


def test_side_is_an_undoable_session_setting(window, demo):
    window.open_project(demo)
    panel = window.knee_panel
    assert panel.side.currentData() is None
    panel.side.setCurrentIndex(2)
    panel.side.activated.emit(2)
    assert window.session.side == "left" and window.isWindowModified()
    window.edit.undo_action.trigger()
    assert window.session.side is None
    assert panel.side.currentData() is None


def test_missing_poses_say_why(window, demo):
    window.open_project(demo)
    window.session.project.poses.clear()
    window.presenters.kinematics.refresh_knee()
    assert "No kinematics" in window.knee_panel.status.text()
    assert window.knee_panel.value_labels[0].text() == "–"


def test_export_dialog_writes_the_chosen_files(window, demo, tmp_path, monkeypatch):
    window.open_project(demo)
    put_truth(window.session)

    def exec_(dialog):
        dialog.folder.setText(str(tmp_path / "out"))
        dialog.checks["tra"].setChecked(True)
        dialog.checks["plot"].setChecked(True)
        return QDialog.DialogCode.Accepted

    (tmp_path / "out").mkdir()
    monkeypatch.setattr(ExportDialog, "exec", exec_)
    window.knee.export_results()
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert names == ["demo.tra", "demo_kinematics.csv", "demo_kinematics.png", "demo_poses.csv"]
    assert "Exported 4 files" in window.statusBar().currentMessage()
    assert "flagged for review" not in window.statusBar().currentMessage()
    # a pose the matcher flagged and nobody accepted stays out of the .tra, and the user is told
    record = window.session.project.poses[(1, "tibial")]
    window.session.project.poses[(1, "tibial")] = PoseRecord(record.pose, status="needs_review", reason="test")
    window.knee.export_results()
    assert "1 pose flagged for review and left out of .tra as NaN" in window.statusBar().currentMessage()
    assert (tmp_path / "out" / "demo.tra").read_text().splitlines()[1].split(",")[16] == "NaN"


def test_export_to_a_missing_folder_gives_one_dialog(window, demo, tmp_path, monkeypatch, dialogs):
    window.open_project(demo)

    def exec_(dialog):
        dialog.folder.setText(str(tmp_path / "absent"))
        return QDialog.DialogCode.Accepted

    monkeypatch.setattr(ExportDialog, "exec", exec_)
    window.knee.export_results()
    assert len(dialogs["warning"]) == 1 and "folder does not exist" in dialogs["warning"][0][2]


def test_import_poses_lands_as_placed_and_undoes_in_one_step(window, demo, tmp_path):
    window.open_project(demo)
    session = window.session
    put_truth(session)
    from fluorogui.workflow.exports import export_tra

    export_tra(session, tmp_path / "p.tra")
    session.project.poses.clear()
    assert window.knee.import_poses_file(str(tmp_path / "p.tra")) == 2 * len(session.frames)
    assert all(r.status == "placed" for r in session.project.poses.values())
    window.edit.undo_action.trigger()
    assert not session.project.poses


def test_a_pose_file_read_with_a_note_says_so_in_one_dialog(window, demo, tmp_path, dialogs):
    """An input repaired on reading (here a JointTrack header in lower case) is imported, and
    the app says what was done to which file: the command line's stderr line, as a dialog."""
    window.open_project(demo)
    session = window.session
    put_truth(session)
    from fluorogui.workflow.exports import export_jts

    path = export_jts(session, tmp_path, 0, include_unreviewed=True)[0]
    path.write_text(path.read_text().replace("JT_EULER_312", "jt_euler_312", 1))
    component = "femoral" if "fem" in path.name else "tibial"
    session.project.poses.clear()
    assert window.knee.import_poses_file(str(path), component=component, view=0) == len(session.frames)
    assert len(dialogs["warning"]) == 1
    title, text = dialogs["warning"][0][1:3]
    assert title == "Imported poses with notes"
    assert f"{path}: the header 'jt_euler_312' is not in capitals" in text
    # a file read as it stands: no dialog
    export_jts(session, tmp_path, 0, include_unreviewed=True)
    assert window.knee.import_poses_file(str(path), component=component, view=0) == len(session.frames)
    assert len(dialogs["warning"]) == 1


def test_pose_changes_refresh_the_dock_once_the_burst_is_over(window, demo, qtbot):
    window.open_project(demo)
    session = window.session
    for frame, by in session.project.settings["demo_truth"].items():
        for c, pose in by.items():
            session.set_pose(c, int(frame), np.asarray(pose, float))
    assert window.presenters.kinematics.refresh_timer.isActive()  # one refresh pending, not one per pose
    expected = f"{session.knee_at(window.controller.frame).values.flexion_deg:.2f}"
    qtbot.waitUntil(lambda: window.knee_panel.value_labels[0].text() == expected, timeout=3000)
    assert not window.presenters.kinematics.refresh_timer.isActive()


def test_a_relinked_mesh_refreshes_the_dock_with_its_own_anatomical_frame(window, demo, tmp_path):
    import pyvista as pv

    window.open_project(demo)
    session = window.session
    put_truth(session)
    window.presenters.kinematics.refresh_knee()
    before = [label.text() for label in window.knee_panel.value_labels]
    vertices, faces = session.raw_mesh("tibial")
    moved = tmp_path / "tray_moved.stl"
    pv.PolyData(vertices + [10.0, 0.0, 0.0], np.column_stack([np.full(len(faces), 3), faces]).ravel()).save(moved)
    session.relink_mesh("tibial", moved)  # the tray's origin 10 mm on: its translations change at once
    after = [label.text() for label in window.knee_panel.value_labels]
    assert after != before
    row = session.knee_at(window.controller.frame)
    assert after[0] == f"{row.values.flexion_deg:.2f}"
