"""The session controller: a thin Qt adapter over the workflow's Session. Its signals carry
frame numbers, the Undo / Redo actions move the session's own history and follow it when
it moves by itself, panel edits enter that history as single steps, and an open project
file is locked."""
import json
import os
import socket

import numpy as np
import pytest

pytest.importorskip("pytestqt")

import pyvista as pv  # noqa: E402
from PySide6.QtGui import QAction  # noqa: E402

from fluorogui.core.records import ImageSequence, MatchRecord, ModelEntry, PoseRecord, Project
from fluorogui.core.status import Status
from fluorogui.gui.actions.undo import UndoActions  # noqa: E402
from fluorogui.gui.controller import SessionController  # noqa: E402
from fluorogui.io.project.lock import ProjectLocked, lock_path, read_holder  # noqa: E402
from fluorogui.simulation.phantoms import femoral_component_mesh  # noqa: E402
from fluorogui.simulation.protocols import dual_orthogonal_views  # noqa: E402
from fluorogui.workflow.session import FrameState  # noqa: E402

SQUARE = np.array([[10, 10], [50, 10], [50, 50], [10, 50.0]])


@pytest.fixture()
def project(tmp_path):
    vertices, faces = femoral_component_mesh()
    mesh_path = tmp_path / "femur.stl"
    pv.PolyData(vertices, np.hstack([np.full((len(faces), 1), 3), faces]).ravel()).save(str(mesh_path))
    views = list(dual_orthogonal_views(image_size=(256, 256)))
    return Project(views=views, sequences=[ImageSequence([tmp_path / f"v{k}_{i}.png" for i in range(3)])
                                           for k in range(2)],
                   frames=[0, 5, 10], models=[ModelEntry("femoral", mesh_path)])


@pytest.fixture()
def controller(qtbot, project):
    c = SessionController()
    c.set_project(project, None)
    return c


def test_frame_signals_carry_frame_numbers(controller, qtbot):
    c = controller
    assert c.frame == 0
    with qtbot.waitSignal(c.frame_changed) as blocker:
        c.set_frame(10)
    assert blocker.args == [10] and c.frame == 10 and c.frame_index == 2
    with qtbot.assertNotEmitted(c.frame_changed):
        c.set_frame(7)  # no such frame
    c.step_frame(-1)
    assert c.frame == 5
    with qtbot.waitSignal(c.pose_changed) as blocker:
        c.session.set_pose("femoral", 5, np.ones(6))
    assert blocker.args == [5, "femoral"]


def test_undo_redo_actions_change_the_session(controller, qtbot):
    c, s = controller, controller.session
    undo = UndoActions(s.history, QAction("&Undo", c), QAction("&Redo", c))
    assert not c.dirty and not undo.undo_action.isEnabled()
    start = s.pose("femoral", 0)
    target = start + np.array([1, 2, 3, 4, 5, 6.0])
    with qtbot.waitSignal(c.dirty_changed) as blocker:
        s.set_pose("femoral", 0, target)
    assert blocker.args == [True]
    assert len(s.history) == 1 and undo.undo_action.text() == "&Undo Move model"
    undo.undo_action.trigger()
    assert s.pose_record("femoral", 0) is None and not c.dirty and s.history.index == 0
    undo.redo_action.trigger()
    np.testing.assert_allclose(s.pose("femoral", 0), target)
    assert s.history.index == 1 and c.dirty


def test_the_undo_actions_follow_the_history_when_it_moves_by_itself(controller):
    c, s = controller, controller.session
    undo = UndoActions(s.history, QAction("&Undo", c), QAction("&Redo", c))
    modified = []
    c.dirty_changed.connect(modified.append)
    s.set_pose("femoral", 0, np.ones(6))
    s.set_outline((0, 1, "femoral"), SQUARE)
    assert len(s.history) == 2 and undo.undo_action.text() == "&Undo Edit outline"
    s.history.undo()  # a script undoes: the actions show it, nothing is undone a second time
    assert undo.undo_action.text() == "&Undo Move model" and undo.redo_action.text() == "&Redo Edit outline"
    assert s.history.index == 1
    assert s.outline_record((0, 1, "femoral")) is None and s.pose_record("femoral", 0) is not None
    s.history.redo()
    assert undo.undo_action.text() == "&Undo Edit outline" and not undo.redo_action.isEnabled()
    assert s.outline_record((0, 1, "femoral")) is not None
    s.history.set_clean()
    assert modified[-1] is False and not c.dirty
    s.history.reset_clean()
    assert modified[-1] is True and c.dirty


def test_mergeable_nudges_are_one_step_and_macros_one_entry(controller):
    c, s = controller, controller.session
    undo = UndoActions(s.history, QAction("&Undo", c), QAction("&Redo", c))
    for k in range(4):
        s.set_pose("femoral", 0, np.full(6, float(k)), text="Edit pose", mergeable=True)
    assert len(s.history) == 1 and undo.undo_action.text() == "&Undo Edit pose"
    s.history.begin_macro("Match femoral in frame 0")
    s.set_outline((0, 0, "femoral"), SQUARE, reviewed=False)
    s.set_outline((0, 1, "femoral"), SQUARE, reviewed=False)
    s.set_pose("femoral", 0, np.ones(6))
    s.history.end_macro()
    assert len(s.history) == 2 and undo.undo_action.text() == "&Undo Match femoral in frame 0"
    undo.undo_action.trigger()
    assert s.outline_record((0, 0, "femoral")) is None
    np.testing.assert_allclose(s.pose("femoral", 0), np.full(6, 3.0))


def test_a_panel_edit_is_one_reviewed_step_with_the_panels_own_state(controller):
    c, s = controller, controller.session
    undo = UndoActions(s.history, QAction("&Undo", c), QAction("&Redo", c))
    erased = []
    key = c.outline_key(1)
    c.apply_edit("Erase edges and 2 points", (key, SQUARE), [(lambda: erased.append(1), lambda: erased.pop())])
    assert erased == [1] and s.outline_record(key).reviewed
    assert len(s.history) == 1 and undo.undo_action.text() == "&Undo Erase edges and 2 points"
    assert s.frame_state(0) == FrameState.OUTLINED
    undo.undo_action.trigger()
    assert erased == [] and s.outline_record(key) is None and s.frame_state(0) == FrameState.EMPTY
    undo.redo_action.trigger()
    assert erased == [1] and s.outline_points(key) is not None


def test_a_placed_pose_shows_its_frame_as_outlined_or_placed(controller):
    # what the timeline's legend says: amber for "outlined or placed" (a pose found or
    # moved there by hand before any match); grey again once the placing is undone
    s = controller.session
    assert s.frame_state(5) == FrameState.EMPTY
    s.set_pose("femoral", 5, np.ones(6))
    assert s.frame_state(5) == FrameState.OUTLINED and s.frame_state(10) == FrameState.EMPTY
    s.history.undo()
    assert s.frame_state(5) == FrameState.EMPTY


def test_frame_states_never_show_a_flagged_pose_as_matched(controller):
    s = controller.session
    record = MatchRecord(0.2, [0.1, 0.1], 30, 0.1, True, "fast")
    s.set_record("femoral", 0, PoseRecord(np.zeros(6), record, status=Status.MATCHED), "Match")
    assert s.frame_state(0) == FrameState.MATCHED
    s.set_record("femoral", 5, PoseRecord(np.zeros(6), record, status=Status.NEEDS_REVIEW, reason="view 1: too far"),
                 "Match")
    assert s.frame_state(5) == FrameState.NEEDS_REVIEW
    s.set_reviewed("femoral", 5)
    assert s.frame_state(5) == FrameState.REVIEWED


def test_open_locks_the_file_and_save_reopen_gives_the_same_session(controller, project, tmp_path, qtbot):
    c, s = controller, controller.session
    s.set_pose("femoral", 5, [1, 2, 3, 4, 5, 6])
    c.set_frame(5)
    path = tmp_path / "s.fluoro"
    c.save(path)
    assert not c.dirty and read_holder(path)["pid"] == os.getpid()
    other = SessionController()
    other.open(path)  # the same process may open it again
    assert other.project == s.project and other.frame == 5  # the frame on screen comes back
    other.close()
    assert lock_path(path).exists()  # still held by the first controller
    c.set_project(Project(), None)  # another project replaces it: the lock goes
    assert not lock_path(path).exists()


def test_a_file_another_program_holds_is_refused_or_opened_read_only(controller, project, tmp_path):
    from fluorogui.io.project.document import save_project

    path = tmp_path / "held.fluoro"
    save_project(project, path)
    holder = {"program": "fluorogui track", "pid": os.getppid(), "host": socket.gethostname(), "user": "x",
              "since": 0}
    lock_path(path).write_text(json.dumps(holder))
    c = controller
    before = c.project
    with pytest.raises(ProjectLocked, match="fluorogui track"):
        c.open(path)
    assert c.project is before
    c.open(path, read_only=True)
    assert c.read_only and c.path == path and c.lock is None
    from fluorogui.io.errors import InputError

    with pytest.raises(InputError, match="read-only"):
        c.save()
    copy = tmp_path / "copy.fluoro"
    c.save(copy)  # Save As to another file works and takes that file's lock
    assert not c.read_only and read_holder(copy)["pid"] == os.getpid()
    assert read_holder(path)["program"] == "fluorogui track"  # the other program's lock is untouched
