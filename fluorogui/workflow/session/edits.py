"""The session's undoable edits: poses set by hand, placed from clicks or turned to a
preset, review flags, outlines and a model's mesh file. A part of ``Session``: it is given
the project, the history, the cache (for outline splines), the reader (the poses' stand-ins,
meshes) and ``notify``; every edit is one ``Command`` on the history and tells the
listeners what changed."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from fluorogui.core.outlines.spline import OutlineError, OutlineSpline
from fluorogui.core.projection.geometry import triangulate
from fluorogui.core.projection.pose import as_pose, rotation_matrix
from fluorogui.core.records import OutlineRecord, PoseRecord, Project
from fluorogui.io.meshes.read import load_mesh
from fluorogui.workflow.session.cache import SessionCache
from fluorogui.workflow.session.events import SessionEvent
from fluorogui.workflow.session.history import Command, CommandStack
from fluorogui.workflow.session.reader import Reader

ORIENTATION_PRESETS = (
    ("Upright (all angles 0)", (0.0, 0.0, 0.0)),
    ("Flexed 30°", (30.0, 0.0, 0.0)),
    ("Flexed 60°", (60.0, 0.0, 0.0)),
    ("Flexed 90°", (90.0, 0.0, 0.0)),
    ("Turned 180° about y", (0.0, 180.0, 0.0)),
)


def fitted_outline(points: np.ndarray, weights: np.ndarray | None = None) -> OutlineSpline | None:
    """The spline through an outline (with its points' weights), or None while the
    outline cannot carry one."""
    try:
        return OutlineSpline.fit(points, weights=weights)
    except (OutlineError, ValueError):
        return None


class Edits:
    """Undoable edits of a session's poses, review flags, outlines and mesh files.

    Parameters
    ----------
    project : fluorogui.core.records.Project
    history : CommandStack
        Where every edit goes, as one ``Command``.
    cache : SessionCache
        Its ``splines`` (fitted once per outline record) and meshes (dropped on relinking).
    reader : Reader
        The poses' stand-ins and the meshes.
    notify : callable
        ``notify(event, what)`` after every change (``SessionEvent``).
    """

    def __init__(self, *, project: Project, history: CommandStack, cache: SessionCache, reader: Reader,
                 notify: Callable[[str, object], None]) -> None:
        self.project = project
        self.history = history
        self.cache = cache
        self.reader = reader
        self.notify = notify

    # -- poses ---------------------------------------------------------------------------------
    def set_pose(self, component: str, frame: int, pose, text: str = "Move model", *,
                 mergeable: bool = False) -> None:
        """Set a pose by hand (status ``placed``), as one undoable edit.

        Parameters
        ----------
        component : str
        frame : int
        pose : array_like of 6 float
            mm and degrees (the pose convention).
        text : str, optional
            The edit's name in the undo history.
        mergeable : bool, optional
            Merge with the previous edit if it was also a mergeable move (nudges).

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.set_pose("femoral", 1, [1.5, 7.5, 20.5, 28.0, 1.2, -1.6])
        >>> str(session.pose_record("femoral", 1).status)
        'placed'
        >>> session.history.undo()
        >>> session.pose_record("femoral", 1) is None
        True
        """
        self._push_pose(component, frame, PoseRecord(as_pose(pose)), text, merge_id="move" if mergeable else None)

    def set_record(self, component: str, frame: int, record: PoseRecord | None, text: str) -> None:
        """Store a whole pose record (a match result) through the history."""
        self._push_pose(component, frame, record, text, merge_id=None)

    def set_reviewed(self, component: str, frame: int, reviewed: bool = True) -> None:
        """Accept (or reopen) a component's pose in a frame, as one undoable edit.

        An accepted pose is never changed by matching or tracking, and flagged poses that
        were accepted are written to ``.tra`` and ``.jts`` exports.

        Parameters
        ----------
        component : str
        frame : int
        reviewed : bool, optional
            True to accept, False to reopen.
        """
        before = self.project.poses.get((frame, component))
        if before is None:
            after = PoseRecord(self.reader.pose(component, frame), None, reviewed=reviewed)
        else:
            after = PoseRecord(before.pose.copy(), before.match, reviewed=reviewed, status=before.status,
                               reason=before.reason)
        self._push_pose(component, frame, after, "Accept pose" if reviewed else "Reopen pose", merge_id=None)

    def place_at(self, component: str, frame: int, pixels) -> float:
        """Point-and-click placement in two views, keeping the model's orientation.

        The model's centroid moves to where the rays through ``pixels`` meet (the middle of
        their shortest connection); one undoable edit.

        Parameters
        ----------
        component : str
        frame : int
        pixels : sequence of 2 (u, v)
            The component's centre clicked in view 1 and in view 2 (pixels).

        Returns
        -------
        float
            How far the two rays miss each other (mm): large means the clicks do not show
            the same point.
        """
        point, miss = triangulate(self.project.views[:2], [np.asarray(p, float) for p in pixels])
        pose = self.reader.pose(component, frame)
        R = rotation_matrix(*pose[3:])
        pose[:3] = point - R @ self.reader.mesh(component).centroid
        self.set_pose(component, frame, pose, text="Place model")
        return float(miss)

    def orient(self, component: str, frame: int, angles) -> None:
        """Give the model a preset orientation, turning it about its centroid."""
        pose = self.reader.pose(component, frame)
        centroid = self.reader.mesh(component).centroid
        world_centroid = rotation_matrix(*pose[3:]) @ centroid + pose[:3]
        angles = np.asarray(angles, dtype=float)
        pose[3:] = angles
        pose[:3] = world_centroid - rotation_matrix(*angles) @ centroid
        self.set_pose(component, frame, pose, text="Orientation preset")

    def _push_pose(self, component, frame, after, text, *, merge_id) -> None:
        key = (int(frame), component)
        before = self.project.poses.get(key)
        self.history.push(Command(text, key, before, after, self._store_pose, merge_id))

    def _store_pose(self, key, record: PoseRecord | None) -> None:
        if record is None:
            self.project.poses.pop(key, None)
        else:
            self.project.poses[key] = PoseRecord(record.pose.copy(), record.match, reviewed=record.reviewed,
                                                 status=record.status, reason=record.reason)
        self.notify(SessionEvent.POSE, key)

    # -- models ----------------------------------------------------------------------------------
    def relink_mesh(self, component: str, path) -> None:
        """Point a component at another mesh file (its file moved or is missing): the file
        is loaded first (InputError if it cannot be), then the change is one undoable step."""
        entry = self.project.model(component)
        if entry is None:
            raise KeyError(component)
        path = Path(path)
        load_mesh(path)
        self.history.push(Command(f"Locate the {component} model", component, entry.mesh_path, path,
                                  self._store_mesh_path))

    def _store_mesh_path(self, component: str, path: Path) -> None:
        self.project.model(component).mesh_path = Path(path)
        self.cache.forget_mesh(component)
        self.notify(SessionEvent.MODEL, component)

    # -- outlines ------------------------------------------------------------------------------
    def outline_record(self, key) -> OutlineRecord | None:
        return self.project.records.get(tuple(key))

    def outline_points(self, key) -> np.ndarray | None:
        """A copy of an outline's points, ``(K, 2)`` pixels, or None.

        Parameters
        ----------
        key : tuple
            ``(frame, view, component)``.
        """
        record = self.project.records.get(tuple(key))
        return None if record is None else record.points.copy()

    def set_outline(self, key, points, text: str = "Edit outline", *, reviewed: bool | None = True,
                    weights: np.ndarray | None = None) -> None:
        """Change an outline, as one undoable edit.

        Parameters
        ----------
        key : tuple
            ``(frame, view, component)``.
        points : array_like of shape (K, 2) or None
            Ordered, closed outline in pixels (the last point not a repeat of the first);
            None removes the outline.
        text : str, optional
            The edit's name in the undo history.
        reviewed : bool or None, optional
            True (a user's edit) marks the outline reviewed: matching then uses it as it
            is. None keeps the flag it had.
        weights : array_like of shape (K,), optional
            The points' weights in a match (``OutlineRecord.weights``). Without them an
            outline whose points stay the same keeps its weights (marking it reviewed does
            not change how it matches); an edited one has none.
        """
        key = (int(key[0]), int(key[1]), str(key[2]))
        before = self.project.records.get(key)
        if points is None:
            after = None
        else:
            points = np.asarray(points, dtype=float).reshape(-1, 2)
            keep = before.reviewed if (before is not None and reviewed is None) else bool(reviewed)
            if weights is None and before is not None and np.array_equal(before.points, points):
                weights = before.weights
            after = self._new_record(key, points, keep, weights)
        self.history.push(Command(text, key, before, after, self._store_outline))

    def _new_record(self, key, points: np.ndarray, reviewed: bool, weights=None) -> OutlineRecord:
        """The record keeps the points; ``spline`` fits them when first asked (the same
        spline every time, so neither the file nor storing a tracked frame needs it)."""
        return OutlineRecord(points, None, reviewed=reviewed, weights=weights)

    def _store_outline(self, key, record: OutlineRecord | None) -> None:
        if record is None:
            self.project.records.pop(key, None)
        else:
            self.project.records[key] = record
        self.notify(SessionEvent.OUTLINE, key)

    def spline(self, key) -> OutlineSpline | None:
        """The spline of an outline record (fitted once per record), None if it cannot have one."""
        key = tuple(key)
        record = self.project.records.get(key)
        if record is None or len(record.points) < 4:
            return None
        cached = self.cache.splines.get(key)
        if cached is None or cached[0] is not record:  # e.g. a record loaded from a file
            cached = self.cache.splines[key] = (record, fitted_outline(record.points, record.weights))
        return cached[1]

    def given_splines(self, component: str, frame: int) -> list[OutlineSpline | None] | None:
        """The reviewed outlines of a component per view (None where a view has none, and
        None overall when no view has one): matching uses them as they are."""
        out = []
        for view in range(self.reader.n_views):
            record = self.project.records.get((frame, view, component))
            out.append(self.spline((frame, view, component)) if record is not None and record.reviewed else None)
        return out if any(s is not None for s in out) else None
