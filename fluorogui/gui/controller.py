"""The session controller: the one object that owns the open project and changes it.

Widgets never edit the ``Project`` dataclasses directly; they call the controller, which
records every change as an undoable command (so "dirty" is simply "the undo stack is not
at its clean index") and announces it with a signal. It also caches what is expensive to
reload (images, prepared meshes) and answers questions the widgets ask (current pose,
frame state). No geometry lives here: it calls ``fluorogui.core``.
"""
from __future__ import annotations

import enum
from collections import OrderedDict
from pathlib import Path

import numpy as np
from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QUndoCommand, QUndoStack

from fluorogui.core.geometry import triangulate
from fluorogui.core.mesh import MeshError, PreparedMesh, prepare_mesh
from fluorogui.core.pose import as_pose, rotation_matrix
from fluorogui.core.session import MatchRecord, OutlineRecord, PoseRecord, Project, SplineRecord
from fluorogui.core.spline import OutlineError, OutlineSpline
from fluorogui.io.errors import InputError
from fluorogui.io.images import read_image
from fluorogui.io.meshes import load_mesh
from fluorogui.io.project import load_project, save_project

COMPONENT_ORDER = ("femoral", "tibial")
IMAGE_CACHE_FRAMES = 6


class FrameState(enum.IntEnum):
    """How far the work on one frame has got (the timeline's colours)."""

    EMPTY = 0  # no outline yet
    OUTLINED = 1  # at least one outline
    MATCHED = 2  # every component has a matched pose
    REVIEWED = 3  # every matched pose accepted by the user


def fitted_outline(points: np.ndarray) -> tuple[SplineRecord | None, OutlineSpline | None]:
    """The spline of an outline as stored (SplineRecord) and as used, or None for both
    while the outline cannot carry a spline."""
    try:
        spline = OutlineSpline.fit(points)
    except (OutlineError, ValueError):
        return None, None
    d = spline.to_dict()
    record = SplineRecord(knots=d["knots"], coefficients=d["coefficients"], degree=d["degree"], t_range=d["t_range"])
    return record, spline


class _SetOutline(QUndoCommand):
    def __init__(self, controller: "SessionController", key, before, after, text: str):
        super().__init__(text)
        self.controller, self.key, self.before, self.after = controller, key, before, after

    def redo(self):
        self.controller._store_outline(self.key, self.after)

    def undo(self):
        self.controller._store_outline(self.key, self.before)


class _SetPose(QUndoCommand):
    MERGE_ID = 1701

    def __init__(self, controller: "SessionController", key, before, after, text: str, mergeable: bool):
        super().__init__(text)
        self.controller, self.key, self.before, self.after = controller, key, before, after
        self.mergeable = mergeable

    def id(self):  # noqa: A003 (Qt API)
        return self.MERGE_ID if self.mergeable else -1

    def mergeWith(self, other):  # noqa: N802 (Qt API)
        if not (isinstance(other, _SetPose) and other.mergeable and other.key == self.key):
            return False
        self.after = other.after
        return True

    def redo(self):
        self.controller._store_pose(self.key, self.after)

    def undo(self):
        self.controller._store_pose(self.key, self.before)


class SessionController(QObject):
    """Owns the project, the current frame and component, caches and the undo stack."""

    project_replaced = Signal()
    frame_changed = Signal(int)  # index into project.frames
    component_changed = Signal(str)
    pose_changed = Signal(int, str)  # frame number, component
    outline_changed = Signal(object, str)  # (frame, view, component) key, component
    dirty_changed = Signal(bool)
    path_changed = Signal(object)

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.project = Project()
        self.path: Path | None = None
        self.frame_index = 0
        self.component = COMPONENT_ORDER[0]
        self.undo_stack = QUndoStack(self)
        self.undo_stack.cleanChanged.connect(self._clean_changed)
        self._images: OrderedDict = OrderedDict()
        self._meshes: dict[str, PreparedMesh] = {}
        self._raw_meshes: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._splines: dict = {}  # outline key -> (record, OutlineSpline or None)

    def _clean_changed(self, clean: bool) -> None:
        self.dirty_changed.emit(not clean)

    # -- project lifecycle ------------------------------------------------------------------
    @property
    def dirty(self) -> bool:
        return not self.undo_stack.isClean()

    def set_project(self, project: Project, path: Path | None) -> None:
        """Replace the open project (after it loaded or was built successfully)."""
        self.project = project
        self.path = Path(path) if path else None
        self._images.clear()
        self._meshes.clear()
        self._raw_meshes.clear()
        self._splines.clear()
        self.undo_stack.clear()
        self.undo_stack.setClean()
        self.frame_index = 0
        names = self.components()
        if names and self.component not in names:
            self.component = names[0]
        self.project_replaced.emit()
        self.path_changed.emit(self.path)
        self.dirty_changed.emit(False)
        self.frame_changed.emit(0)

    def open(self, path) -> None:
        """Load a project file; raises InputError and leaves the open project untouched."""
        project = load_project(path)
        self.set_project(project, Path(path))

    def save(self, path=None) -> None:
        """Save (atomically) to ``path`` or the current path; raises InputError."""
        target = Path(path) if path else self.path
        if target is None:
            raise ValueError("no file name to save to")
        self.project.settings.setdefault("gui", {})["frame_index"] = self.frame_index
        save_project(self.project, target)
        if target != self.path:
            self.path = target
            self.path_changed.emit(target)
        self.undo_stack.setClean()

    # -- frames, views, components ---------------------------------------------------------
    @property
    def frames(self) -> list[int]:
        return list(self.project.frames)

    @property
    def frame(self) -> int | None:
        frames = self.project.frames
        return frames[self.frame_index] if frames else None

    def n_views(self) -> int:
        return len(self.project.views)

    def set_frame_index(self, index: int) -> None:
        if not self.project.frames:
            return
        index = int(np.clip(index, 0, len(self.project.frames) - 1))
        if index != self.frame_index:
            self.frame_index = index
            self.frame_changed.emit(index)

    def components(self) -> list[str]:
        names = [m.component for m in self.project.models]
        return sorted(names, key=lambda n: (COMPONENT_ORDER.index(n) if n in COMPONENT_ORDER else 99, n))

    def set_component(self, component: str) -> None:
        if component != self.component:
            self.component = component
            self.component_changed.emit(component)

    # -- data access (cached) --------------------------------------------------------------
    def image_path(self, view: int, index: int | None = None) -> Path | None:
        index = self.frame_index if index is None else index
        if view >= len(self.project.sequences):
            return None
        paths = self.project.sequences[view].paths
        return paths[index] if index < len(paths) else None

    def images(self, index: int | None = None) -> list[np.ndarray | None]:
        """The images of one frame (by index), one per view; raises InputError."""
        index = self.frame_index if index is None else index
        out = []
        for view in range(self.n_views()):
            path = self.image_path(view, index)
            if path is None:
                out.append(None)
                continue
            if path in self._images:
                self._images.move_to_end(path)
            else:
                self._images[path] = read_image(path)
                while len(self._images) > IMAGE_CACHE_FRAMES * max(1, self.n_views()):
                    self._images.popitem(last=False)
            out.append(self._images[path])
        return out

    def raw_mesh(self, component: str) -> tuple[np.ndarray, np.ndarray]:
        """Vertices and faces of a component's mesh in its local frame; raises InputError."""
        if component not in self._raw_meshes:
            entry = self.project.model(component)
            if entry is None:
                raise KeyError(component)
            vertices, faces = load_mesh(entry.mesh_path)
            frame = entry.local_frame
            if not np.allclose(frame, np.eye(4)):
                vertices = vertices @ frame[:3, :3].T + frame[:3, 3]
            self._raw_meshes[component] = (vertices, faces)
        return self._raw_meshes[component]

    def mesh(self, component: str) -> PreparedMesh:
        if component not in self._meshes:
            vertices, faces = self.raw_mesh(component)
            try:
                self._meshes[component] = prepare_mesh(vertices, faces)
            except MeshError as exc:
                raise InputError(self.project.model(component).mesh_path, str(exc)) from None
        return self._meshes[component]

    # -- poses -----------------------------------------------------------------------------
    def pose_record(self, component: str, frame: int | None = None) -> PoseRecord | None:
        frame = self.frame if frame is None else frame
        return self.project.poses.get((frame, component))

    def pose(self, component: str, frame: int | None = None) -> np.ndarray:
        """The component's pose in a frame: its own, else the nearest earlier (then later)
        frame's, else a default placing the model where the two central rays meet."""
        frame = self.frame if frame is None else frame
        record = self.project.poses.get((frame, component))
        if record is not None:
            return record.pose.copy()
        frames = self.project.frames
        if frame in frames:
            i = frames.index(frame)
            for j in list(range(i - 1, -1, -1)) + list(range(i + 1, len(frames))):
                other = self.project.poses.get((frames[j], component))
                if other is not None:
                    return other.pose.copy()
        return self.default_pose(component)

    def default_pose(self, component: str) -> np.ndarray:
        views = self.project.views
        if len(views) >= 2:
            centres = [(np.asarray(v.image_size, dtype=float) - 1) / 2 for v in views[:2]]
            point, _ = triangulate(views[:2], centres)
        else:
            point = np.zeros(3)
        centroid = np.zeros(3)
        try:
            centroid = self.mesh(component).centroid
        except (InputError, KeyError):
            pass
        return np.concatenate([point - centroid, np.zeros(3)])

    def set_pose(self, component: str, pose, frame: int | None = None, match: MatchRecord | None = None,
                 text: str = "Move model", mergeable: bool = False) -> None:
        """Change a pose through the undo stack (a match result carries its record)."""
        frame = self.frame if frame is None else frame
        key = (frame, component)
        before = self.project.poses.get(key)
        after = PoseRecord(as_pose(pose), match, reviewed=False)
        self.undo_stack.push(_SetPose(self, key, before, after, text, mergeable))

    def set_reviewed(self, component: str, reviewed: bool = True, frame: int | None = None) -> None:
        frame = self.frame if frame is None else frame
        key = (frame, component)
        before = self.project.poses.get(key)
        if before is None:
            after = PoseRecord(self.pose(component, frame), None, reviewed=reviewed)
        else:
            after = PoseRecord(before.pose.copy(), before.match, reviewed=reviewed)
        self.undo_stack.push(_SetPose(self, key, before, after, "Accept pose" if reviewed else "Reopen pose", False))

    def place_at(self, component: str, pixels) -> float:
        """Point-and-click placement: move the model's centroid to where the rays through
        ``pixels`` (one per view) meet, keeping its orientation. Returns the rays' miss (mm)."""
        point, miss = triangulate(self.project.views[:2], [np.asarray(p, float) for p in pixels])
        pose = self.pose(component)
        R = rotation_matrix(*pose[3:])
        pose[:3] = point - R @ self.mesh(component).centroid
        self.set_pose(component, pose, text="Place model")
        return float(miss)

    def orient(self, component: str, angles) -> None:
        """Give the model a preset orientation, turning it about its centroid."""
        pose = self.pose(component)
        centroid = self.mesh(component).centroid
        world_centroid = rotation_matrix(*pose[3:]) @ centroid + pose[:3]
        angles = np.asarray(angles, dtype=float)
        pose[3:] = angles
        pose[:3] = world_centroid - rotation_matrix(*angles) @ centroid
        self.set_pose(component, pose, text="Orientation preset")

    def _store_pose(self, key, record: PoseRecord | None) -> None:
        if record is None:
            self.project.poses.pop(key, None)
        else:
            self.project.poses[key] = PoseRecord(record.pose.copy(), record.match, reviewed=record.reviewed)
        self.pose_changed.emit(key[0], key[1])

    # -- outlines --------------------------------------------------------------------------
    def outline_key(self, view: int, component: str | None = None, frame: int | None = None):
        return (self.frame if frame is None else frame, view, component or self.component)

    def outline_points(self, key) -> np.ndarray | None:
        record = self.project.records.get(tuple(key))
        return None if record is None else record.points.copy()

    def outline_record(self, key) -> OutlineRecord | None:
        return self.project.records.get(tuple(key))

    def set_outline(self, key, points, text: str = "Edit outline", reviewed: bool | None = None) -> None:
        """Change an outline through the undo stack (None removes it)."""
        key = tuple(key)
        before = self.project.records.get(key)
        if points is None:
            after = None
        else:
            points = np.asarray(points, dtype=float).reshape(-1, 2)
            keep_reviewed = before.reviewed if (before is not None and reviewed is None) else bool(reviewed)
            after = self._new_record(key, points, keep_reviewed)
        self.undo_stack.push(_SetOutline(self, key, before, after, text))

    def outline_sink(self, key, component: str, points) -> None:
        """What an image panel's undo commands call: store without a second undo entry."""
        key = tuple(key)
        if points is None:
            self._store_outline(key, None)
            return
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        before = self.project.records.get(key)
        self._store_outline(key, self._new_record(key, points, before.reviewed if before else False))

    def _new_record(self, key, points: np.ndarray, reviewed: bool) -> OutlineRecord:
        """An outline record with its spline; the fitted spline is cached for ``spline``."""
        stored, spline = fitted_outline(points)
        record = OutlineRecord(points, stored, reviewed=reviewed)
        self._splines[key] = (record, spline)
        return record

    def _store_outline(self, key, record: OutlineRecord | None) -> None:
        if record is None:
            self.project.records.pop(key, None)
        else:
            self.project.records[key] = record
        self.outline_changed.emit(key, key[2])

    def spline(self, key) -> OutlineSpline | None:
        """The spline of an outline record (fitted once per record), None if it cannot have one."""
        key = tuple(key)
        record = self.project.records.get(key)
        if record is None or len(record.points) < 4:
            return None
        cached = self._splines.get(key)
        if cached is None or cached[0] is not record:  # e.g. a record loaded from a file
            cached = self._splines[key] = (record, fitted_outline(record.points)[1])
        return cached[1]

    def splines(self, component: str, frame: int | None = None) -> list[OutlineSpline] | None:
        """The image outline splines of a component in every view, or None if any is missing."""
        out = [self.spline(self.outline_key(view, component, frame)) for view in range(self.n_views())]
        return None if any(s is None for s in out) else out

    # -- progress of the work --------------------------------------------------------------
    def frame_state(self, frame: int) -> FrameState:
        names = self.components()
        if not names:
            return FrameState.EMPTY
        records = [self.project.poses.get((frame, c)) for c in names]
        if all(r is not None and r.match is not None for r in records):
            return FrameState.REVIEWED if all(r.reviewed for r in records) else FrameState.MATCHED
        n_views = self.n_views()
        if any((frame, v, c) in self.project.records for v in range(n_views) for c in names):
            return FrameState.OUTLINED
        return FrameState.EMPTY

    def frame_states(self) -> list[FrameState]:
        return [self.frame_state(f) for f in self.project.frames]
