"""The session controller: undoable pose and outline changes, dirty state, frame states."""
import numpy as np
import pytest

pytest.importorskip("pytestqt")

from fluorogui.core.phantoms import femoral_component_mesh  # noqa: E402
from fluorogui.core.session import ImageSequence, ModelEntry, Project  # noqa: E402
from fluorogui.core.validation import dual_orthogonal_views  # noqa: E402
from fluorogui.gui.controller import FrameState, SessionController  # noqa: E402
import pyvista as pv  # noqa: E402


@pytest.fixture()
def controller(qtbot, tmp_path):
    vertices, faces = femoral_component_mesh()
    mesh_path = tmp_path / "femur.stl"
    pv.PolyData(vertices, np.hstack([np.full((len(faces), 1), 3), faces]).ravel()).save(str(mesh_path))
    views = list(dual_orthogonal_views(image_size=(256, 256)))
    project = Project(views=views, sequences=[ImageSequence([tmp_path / f"v{k}_{i}.png" for i in range(3)])
                                               for k in range(2)],
                      frames=[0, 5, 10], models=[ModelEntry("femoral", mesh_path)])
    c = SessionController()
    c.set_project(project, None)
    return c


def test_pose_edits_undo_redo_and_dirty(controller, qtbot):
    c = controller
    assert not c.dirty
    start = c.pose("femoral")
    target = start + np.array([1, 2, 3, 4, 5, 6.0])
    with qtbot.waitSignal(c.pose_changed) as blocker:
        c.set_pose("femoral", target)
    assert blocker.args == [0, "femoral"]
    assert c.dirty
    np.testing.assert_allclose(c.pose("femoral"), target)
    c.undo_stack.undo()
    assert ("femoral" not in [k[1] for k in c.project.poses])
    np.testing.assert_allclose(c.pose("femoral"), start)
    assert not c.dirty
    c.undo_stack.redo()
    np.testing.assert_allclose(c.pose("femoral"), target)


def test_later_frames_start_from_the_nearest_earlier_pose(controller):
    c = controller
    pose = np.array([1.0, 2, 3, 10, 20, 30])
    c.set_pose("femoral", pose, frame=0)
    np.testing.assert_allclose(c.pose("femoral", frame=10), pose)
    c.set_pose("femoral", pose + 1, frame=5)
    np.testing.assert_allclose(c.pose("femoral", frame=10), pose + 1)


def test_default_pose_puts_the_model_where_the_central_rays_meet(controller):
    c = controller
    pose = c.pose("femoral")
    centre_world = c.mesh("femoral").centroid + pose[:3]
    for view in c.project.views:
        uv = view.project(centre_world[None])[0]
        np.testing.assert_allclose(uv, (np.asarray(view.image_size) - 1) / 2, atol=1e-6)


def test_place_at_triangulates_two_clicks(controller):
    c = controller
    target = np.array([3.0, -4.0, 5.0])
    pixels = [view.project(target[None])[0] for view in c.project.views]
    miss = c.place_at("femoral", pixels)
    assert miss < 1e-6
    pose = c.pose("femoral")
    np.testing.assert_allclose(pose[:3] + c.mesh("femoral").centroid, target, atol=1e-6)


def test_outline_changes_are_undoable_and_set_frame_state(controller, qtbot):
    c = controller
    assert c.frame_state(0) == FrameState.EMPTY
    square = np.array([[10, 10], [50, 10], [50, 50], [10, 50.0]])
    key = c.outline_key(0)
    with qtbot.waitSignal(c.outline_changed):
        c.set_outline(key, square)
    assert c.outline_record(key).spline is not None
    assert c.frame_state(0) == FrameState.OUTLINED
    c.undo_stack.undo()
    assert c.outline_points(key) is None
    assert c.frame_state(0) == FrameState.EMPTY


def test_matched_then_reviewed_state(controller):
    from fluorogui.core.session import MatchRecord

    c = controller
    record = MatchRecord(0.2, [0.1, 0.1], 30, 0.1, True, "fast")
    c.set_pose("femoral", c.pose("femoral"), match=record)
    assert c.frame_state(0) == FrameState.MATCHED
    c.set_reviewed("femoral")
    assert c.frame_state(0) == FrameState.REVIEWED
    assert c.pose_record("femoral").match == record
    c.undo_stack.undo()
    assert c.frame_state(0) == FrameState.MATCHED


def test_save_reopen_gives_the_same_session(controller, tmp_path):
    c = controller
    c.set_pose("femoral", [1, 2, 3, 4, 5, 6])
    c.set_outline(c.outline_key(1), np.array([[10, 10], [50, 10], [50, 50], [10, 50.0]]))
    c.set_reviewed("femoral")
    path = tmp_path / "s.fluoro"
    c.save(path)
    assert not c.dirty
    other = SessionController()
    other.open(path)
    assert other.project == c.project
