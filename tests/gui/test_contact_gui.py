"""The app's contact views (issue 47): the Kinematics dock's contact plot, computed off the
GUI thread from the session's poses and redrawn when they change; the 3D scene's condyle
points on the tray."""
import numpy as np
import pytest

pytest.importorskip("pytestqt")

from fluorogui.workflow.contact import contact_rows  # noqa: E402
from tests.gui.test_knee_gui import put_truth  # noqa: E402
from tests.gui.test_scene3d import gl_context  # noqa: E402,F401 (a fixture)


def show_contact(window, qtbot):
    presenter, panel = window.presenters.kinematics, window.knee_panel
    panel.plot.setCurrentIndex(panel.plot.findData("contact"))
    qtbot.waitUntil(lambda: not presenter.contact_runner.is_running() and bool(presenter.contact_rows), timeout=10000)
    return presenter, panel


def ap_lines(panel):
    """The AP axes' condyle lines by label: (flexion, AP) arrays."""
    ap = next(ax for ax in panel.axes if ax.get_gid() == "contact_ap")
    return {line.get_label(): np.asarray(line.get_xydata()) for line in ap.get_lines()
            if line.get_label() in ("medial", "lateral")}


def test_dock_switches_to_the_contact_plot_of_the_demo(window, demo, qtbot):
    window.open_project(demo)
    put_truth(window.session)
    window.presenters.kinematics.refresh_knee()
    presenter, panel = show_contact(window, qtbot)
    assert not panel.against.isEnabled()
    expected = contact_rows(window.session)
    assert [r.frame for r in presenter.contact_rows] == [r.frame for r in expected] == [0, 1, 2]
    lines = ap_lines(panel)
    assert set(lines) == {"medial", "lateral"}
    assert all(len(xy) == 0 for xy in lines.values())  # the demo's truth is placed by hand: needs review
    assert len(panel.axes) == 2
    # matched poses: the lines hold every frame's flexion and AP position
    for key, record in list(window.session.project.poses.items()):
        window.session.project.poses[key] = type(record)(record.pose, status="matched")
    presenter.refresh_knee()
    qtbot.waitUntil(lambda: not presenter.contact_runner.is_running() and not presenter.contact_stale
                    and len(ap_lines(panel).get("medial", [])) == 3, timeout=10000)
    expected = contact_rows(window.session)
    for name, xy in ap_lines(panel).items():
        want = np.array([[r.flexion_deg, getattr(r.contact, name).lowest[1]] for r in expected])
        np.testing.assert_allclose(xy, want, atol=1e-9)
    panel.plot.setCurrentIndex(panel.plot.findData("kinematics"))
    assert len(panel.axes) == 7 and panel.against.isEnabled()


def test_contact_follows_pose_changes(window, demo, qtbot):
    window.open_project(demo)
    put_truth(window.session)
    window.presenters.kinematics.refresh_knee()
    presenter, panel = show_contact(window, qtbot)
    before = presenter.contact_rows[1].contact.medial.lowest.copy()
    pose = window.session.pose("tibial", 1).copy()
    pose[1] += 3.0  # the tray 3 mm further along world y: the points on it move
    window.session.set_pose("tibial", 1, pose)
    qtbot.waitUntil(lambda: not presenter.contact_stale and not presenter.contact_runner.is_running()
                    and not np.allclose(presenter.contact_rows[1].contact.medial.lowest, before), timeout=10000)
    after = contact_rows(window.session, frames=[1])[0].contact.medial.lowest
    np.testing.assert_allclose(presenter.contact_rows[1].contact.medial.lowest, after, atol=1e-9)


def test_an_unreadable_femoral_model_says_why(window, demo, qtbot):
    window.open_project(demo)
    put_truth(window.session)
    panel = window.knee_panel
    panel.plot.setCurrentIndex(panel.plot.findData("contact"))
    entry = window.session.project.model("femoral")
    entry.mesh_path.write_text("not a mesh")
    window.session.cache.forget_mesh("femoral")
    window.session.cache.anatomical_frames.clear()
    window.presenters.kinematics.refresh_knee()
    qtbot.waitUntil(lambda: not window.presenters.kinematics.contact_runner.is_running(), timeout=10000)
    assert panel.contact_note.startswith("No contact: ") and entry.mesh_path.name in panel.contact_note
    assert panel.axes == [] and panel.figure.texts[0].get_text() == panel.contact_note


@pytest.mark.usefixtures("gl_context")
def test_view_toggle_puts_the_condyle_points_on_the_tray(qtbot, tmp_path, monkeypatch, demo, dialogs):
    from PySide6.QtCore import QSettings

    from fluorogui.core.projection.pose import pose_to_matrix
    from fluorogui.gui.main_window import MainWindow

    monkeypatch.setenv("FLUOROGUI_DATA_DIR", str(tmp_path / "appdata"))
    monkeypatch.setenv("FLUOROGUI_NO_GL", "1")  # the off-screen scene, as on a machine without OpenGL
    window = MainWindow(settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat), with_3d=True)
    qtbot.addWidget(window)
    window.open_project(demo)
    session = window.session
    put_truth(session)
    presenter, scene = window.presenters.kinematics, window.widgets.scene.scene
    presenter.refresh_knee()
    assert scene.contact_actor is None and presenter.contact_rows == []  # not computed while nobody asks
    action = window.actions_by_id["view.contact_points"]
    action.trigger()
    qtbot.waitUntil(lambda: scene.contact_actor is not None, timeout=10000)

    def shown():
        return np.asarray(scene.contact_actor.mapper.dataset.points)

    def on_femur(frame, points):
        """Distance of each point to the femoral component's surface vertices, in world."""
        vertices, _ = session.raw_mesh("femoral")
        matrix = pose_to_matrix(session.pose("femoral", frame))
        world = vertices @ matrix[:3, :3].T + matrix[:3, 3]
        return [np.min(np.linalg.norm(world - p, axis=1)) for p in points]

    for frame in (window.controller.frame, 2):
        window.controller.set_frame(frame)
        row = contact_rows(session, frames=[frame])[0]
        to_world = pose_to_matrix(session.pose("tibial", frame)) @ session.anatomical_frame("tibial")
        want = [to_world[:3, :3] @ getattr(row.contact, n).lowest + to_world[:3, 3] for n in ("medial", "lateral")]
        np.testing.assert_allclose(shown(), want, atol=1e-6)
        assert max(on_femur(frame, shown())) < 1.0  # on the femoral surface (measured 0.43-0.70 mm from a vertex)
        assert scene.contact_actor.visibility
    # the tray moved: the points move with it at once
    pose = session.pose("tibial", 2).copy()
    before = shown().copy()
    pose[2] += 4.0
    session.set_pose("tibial", 2, pose)
    np.testing.assert_allclose(shown() - before, [[0, 0, 4.0]] * 2, atol=1e-6)
    action.trigger()
    assert not action.isChecked() and not scene.contact_actor.visibility
    session.history.set_clean()
    window.close()
