"""The session's parts are plain objects with their dependencies named in their constructors:
they work without a Session, Session hands its methods over to them with the same
signatures, and the caches they share are cleared in one place."""
from __future__ import annotations

import inspect

import numpy as np
import pytest

from fluorogui.core.records import Project
from fluorogui.io.project.document import load_project
from fluorogui.workflow import Session
from fluorogui.workflow.session.cache import SessionCache
from fluorogui.workflow.session.edits import Edits
from fluorogui.workflow.session.events import SessionEvent
from fluorogui.workflow.session.history import CommandStack
from fluorogui.workflow.session.knee import Knee
from fluorogui.workflow.session.reader import Reader
from fluorogui.workflow.session.work import Work

PARTS = {"reader": Reader, "edits": Edits, "work": Work, "knee": Knee}


def test_session_is_no_mixin_but_composes_its_parts():
    assert Session.__mro__ == (Session, object)
    session = Session(Project())
    for name, cls in PARTS.items():
        assert isinstance(getattr(session, name), cls)
    assert session.edits.reader is session.reader and session.work.edits is session.edits
    assert session.edits.history is session.history is session.work.history is session.knee.history


@pytest.mark.parametrize("part", PARTS)
def test_every_method_handed_over_keeps_the_parts_signature_and_docstring(part):
    cls = PARTS[part]
    handed = 0
    for name, member in vars(cls).items():
        if name.startswith("_") or name not in vars(Session):
            continue
        mine = vars(Session)[name]
        if isinstance(member, property):
            assert isinstance(mine, property) and mine.__doc__ == member.__doc__, name
        else:
            assert inspect.signature(mine) == inspect.signature(member), name
            assert mine.__doc__ == member.__doc__, name
        handed += 1
    assert handed >= {"reader": 18, "edits": 11, "work": 9, "knee": 9}[part]


def test_edits_and_knee_work_on_a_project_without_a_session(demo):
    project, history, cache, heard = load_project(demo), CommandStack(), SessionCache(), []
    reader = Reader(project, cache)
    edits = Edits(project=project, history=history, cache=cache, reader=reader,
                  notify=lambda event, what: heard.append((event, what)))
    pose = [1.5, 7.5, 20.5, 28.0, 1.2, -1.6]
    edits.set_pose("femoral", 1, pose)
    assert np.allclose(project.poses[(1, "femoral")].pose, pose)
    assert heard == [(SessionEvent.POSE, (1, "femoral"))]
    history.undo()
    assert (1, "femoral") not in project.poses

    knee = Knee(project=project, history=history, cache=cache, reader=reader, notify=lambda *_: None)
    frame = knee.anatomical_frame("tibial")
    assert set(cache.anatomical_frames) == {"tibial"}
    assert np.allclose(frame[3], [0, 0, 0, 1])


def test_replace_project_gives_the_parts_the_new_project_and_drops_the_caches(demo):
    session = Session.open(demo)
    session.anatomical_frame("femoral")
    session.mesh("tibial")
    assert session.cache.anatomical_frames and session.cache.meshes and session.cache.raw_meshes
    other = load_project(demo)
    session.replace_project(other, demo)
    assert not (session.cache.anatomical_frames or session.cache.meshes or session.cache.raw_meshes)
    for name in PARTS:
        assert getattr(session, name).project is other
    session.set_pose("tibial", 1, np.zeros(6))
    assert (1, "tibial") in other.poses


def test_another_mesh_file_gives_its_own_default_anatomical_frame(demo, tmp_path):
    import pyvista as pv

    session = Session.open(demo)
    before = session.default_anatomical_frame("tibial")
    vertices, faces = session.raw_mesh("tibial")
    moved = tmp_path / "tray_moved.stl"
    pv.PolyData(vertices + [10.0, 0.0, 0.0], np.column_stack([np.full(len(faces), 3), faces]).ravel()).save(moved)
    session.relink_mesh("tibial", moved)
    after = session.default_anatomical_frame("tibial")
    assert np.allclose(after[:3, 3] - before[:3, 3], [10.0, 0.0, 0.0], atol=1e-3)  # found on the new file
    assert np.allclose(after[:3, :3], before[:3, :3], atol=1e-6)
    session.history.undo()
    assert np.allclose(session.default_anatomical_frame("tibial"), before)
