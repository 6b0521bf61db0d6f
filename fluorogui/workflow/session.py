"""The Qt-free session: one open project and everything done to it.

``Session`` is what the desktop app, the command line and scripts share (the pattern of
glue's Application or MNE's coreg under its GUI). It owns:

* the project, its file and saving (atomic, with a backup);
* frame access by frame number (the ``frame`` column of pairs.csv) - never by index;
* caches of what is costly to load (images, prepared meshes, splines);
* every edit as an undoable ``Command`` on ``history`` (poses, outlines, review flags);
  the app's Qt undo stack only mirrors it;
* the pose fallback, placement from two clicks and the orientation presets;
* the work: ``match``, ``find`` and ``track`` (see ``work.py``), each also available as a
  job that runs in a worker thread or another process and returns results that
  ``store`` puts into the project on the caller's thread.

Listeners (``session.listeners``) hear every change as ``listener(event, what)``, the
events and what each carries listed in ``workflow.events.SessionEvent``. The knee's side, anatomical frames and
kinematics come from ``KneeMixin`` (``knee.py``); the undoable edits of poses, outlines
and review flags from ``EditsMixin`` (``edits.py``).
"""
from __future__ import annotations

import enum
import json
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from fluorogui.core.projection.geometry import triangulate
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.records import ImageSequence, ModelEntry, PoseRecord, Project
from fluorogui.io.corrections import read_view_image
from fluorogui.io.errors import InputError
from fluorogui.io.meshes.model import prepared_model, read_model
from fluorogui.io.meshes.read import load_mesh
from fluorogui.io.project.document import journal_frames, load_project, save_project
from fluorogui.workflow.edits import EditsMixin, fitted_outline  # noqa: F401 (fitted_outline: its old home)
from fluorogui.workflow.events import SessionEvent
from fluorogui.workflow.history import Command, CommandStack
from fluorogui.workflow.knee import KneeMixin
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.settings import SETTINGS_KEY, WorkflowSettings
from fluorogui.workflow.work import WorkMixin

COMPONENT_ORDER = ("femoral", "tibial")
IMAGE_CACHE_FRAMES = 6
#: Default depth of a model along a single view's central ray, as a fraction of the source-intensifier distance.
SINGLE_PLANE_DEPTH = 0.85
ORIENTATION_PRESETS = (
    ("Upright (all angles 0)", (0.0, 0.0, 0.0)),
    ("Flexed 30°", (30.0, 0.0, 0.0)),
    ("Flexed 60°", (60.0, 0.0, 0.0)),
    ("Flexed 90°", (90.0, 0.0, 0.0)),
    ("Turned 180° about y", (0.0, 180.0, 0.0)),
)


class FrameState(enum.IntEnum):
    """How far the work on one frame has got (the timeline's colours)."""

    EMPTY = 0  # no outline, no pose
    OUTLINED = 1  # at least one outline or placed pose
    MATCHED = 2  # every component matched and passing its checks
    REVIEWED = 3  # every component accepted by the user
    NEEDS_REVIEW = 4  # a component failed its checks (or could not be matched)


class Session(EditsMixin, WorkMixin, KneeMixin):
    """One open project, its undo history and the work done on it.

    The object the desktop app, the command line and scripts share: the same frame and
    settings give the same pose in all three. Frames are addressed by their frame numbers
    (the ``frame`` column of ``pairs.csv``), never by position. Every edit (a pose, an
    outline, a review flag, a stored result) is an undoable command on ``history``.

    Parameters
    ----------
    project : fluorogui.core.records.Project, optional
        The project to work on; a new, empty one when omitted.
    path : str or os.PathLike, optional
        The project's file, where :meth:`save` writes by default.

    Attributes
    ----------
    project : fluorogui.core.records.Project
        Views, image sequences, models, outlines, poses and settings.
    path : pathlib.Path or None
        The project file, or None for a session never saved.
    history : fluorogui.workflow.history.CommandStack
        The undo history: ``history.undo()``, ``history.redo()``.
    listeners : list of callable
        Called as ``listener(event, what)`` on every change, ``event`` a
        :class:`~fluorogui.workflow.events.SessionEvent` (a ``str``: ``"pose"``,
        ``"outline"``, ``"knee"``, ``"model"``, ``"project"``, ``"saved"``), ``what`` as it
        lists.

    See Also
    --------
    Session.open : A session on a project file.
    fluorogui.io.importer.import_folder : A project from a data folder.

    Examples
    --------
    The built-in demo, built once into ``cache/`` (here at 256 × 256 pixels):

        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.frames
        [0, 1]
        >>> session.components()
        ['femoral', 'tibial']
        >>> session.n_views
        2
    """

    def __init__(self, project: Project | None = None, path=None) -> None:
        self.project = project or Project()
        self.path: Path | None = Path(path) if path else None
        self.history = CommandStack()
        self.listeners: list[Callable[[str, object], None]] = []
        self._images: OrderedDict = OrderedDict()
        self._cache_lock = threading.RLock()
        self._meshes: dict[str, PreparedMesh] = {}
        self._raw_meshes: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._splines: dict = {}
        self.dirty_on_disk = False  # frames in the project's journal, not yet in its file
        self._journaled_settings: str | None = None

    # -- project lifecycle ---------------------------------------------------------------------
    @classmethod
    def open(cls, path) -> "Session":
        """A session on a project file.

        Parameters
        ----------
        path : str or os.PathLike
            A ``.fluoro`` project. Older schemas are upgraded in memory (and written in the
            current schema on the next save).

        Returns
        -------
        Session

        Raises
        ------
        fluorogui.io.errors.InputError
            The file is missing, unreadable, not a project, of a newer schema, or
            contradicts itself; the message names the file and the field.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.path.name
        'demo.fluoro'
        """
        return cls(load_project(path), Path(path))

    @classmethod
    def of_images(cls, views, image_paths, models: dict) -> "Session":
        """A session of one frame (numbered 0) from files: what ``fluorogui match`` works on.

        Parameters
        ----------
        views : sequence of fluorogui.core.projection.geometry.View
            The calibrated views (one or two), e.g. from
            :func:`fluorogui.io.calibration.load_view`.
        image_paths : sequence of str or os.PathLike
            One image per view; ``FILE@N`` is frame N of a multi-frame file or video.
        models : dict of str to path
            Component name (``"femoral"``, ``"tibial"``) to mesh file.

        Returns
        -------
        Session
            Unsaved (``path`` is None) until :meth:`save` is given a path.
        """
        project = Project(views=list(views), sequences=[ImageSequence([Path(p)]) for p in image_paths], frames=[0],
                          models=[ModelEntry(name, Path(path)) for name, path in models.items()])
        return cls(project)

    def replace_project(self, project: Project, path=None) -> None:
        """Put another project in this session (after it loaded); clears caches and history."""
        self.project = project
        self.path = Path(path) if path else None
        with self._cache_lock:
            self._images.clear()
        self._meshes.clear()
        self._raw_meshes.clear()
        self._splines.clear()
        self.__dict__.pop("_default_frames", None)
        self.history.clear()
        self._notify(SessionEvent.PROJECT, None)

    def save(self, path=None) -> Path:
        """Save the project atomically; the previous file is kept as ``NAME.fluoro.bak``.

        Parameters
        ----------
        path : str or os.PathLike, optional
            Where to save; by default the session's own file. Becomes the session's file.

        Returns
        -------
        pathlib.Path
            The file written.

        Raises
        ------
        ValueError
            No path was given and the session has none.
        fluorogui.io.errors.InputError
            The file could not be written (the message names it).

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.set_pose("femoral", 1, [1.5, 7.5, 20.5, 28.0, 1.2, -1.6])
        >>> session.dirty
        True
        >>> session.save("edited.fluoro").name
        'edited.fluoro'
        >>> session.dirty
        False
        """
        target = Path(path) if path else self.path
        if target is None:
            raise ValueError("no file name to save to")
        save_project(self.project, target)
        self.path = target
        self.dirty_on_disk = False
        self._journaled_settings = json.dumps(self.project.settings, sort_keys=True, default=str)
        self.history.set_clean()
        self._notify(SessionEvent.SAVED, target)
        return target

    def save_frames(self, results) -> None:
        """Save the stored results' frames without rewriting the project.

        Their pose records and automatic outlines (and the settings, when they changed) are
        appended to the project's journal (``io.project.journal``), which opening the
        project takes in and the next full :meth:`save` folds into the file. What
        :meth:`track` does with ``autosave`` between full saves.

        Parameters
        ----------
        results : iterable of FrameResult
            Results already stored (:meth:`store`); kept ones are left out.

        Raises
        ------
        ValueError
            The session has no file name yet (save it once with :meth:`save`).
        fluorogui.io.errors.InputError
            The journal cannot be written.
        """
        if self.path is None:
            raise ValueError("no file name to save to")
        results = [r for r in results if not r.kept]
        settings = json.dumps(self.project.settings, sort_keys=True, default=str)
        changed = settings != getattr(self, "_journaled_settings", None)
        journal_frames(self.project, self.path, [(r.frame, r.component) for r in results],
                       [(r.frame, v, r.component) for r in results for v in range(self.n_views)], settings=changed)
        self._journaled_settings = settings
        self.dirty_on_disk = True
        self.history.set_clean()

    @property
    def dirty(self) -> bool:
        """True when there are edits since the last save (or since opening)."""
        return self.history.dirty

    def _notify(self, event: str, what) -> None:
        for listener in list(self.listeners):
            listener(event, what)

    # -- settings ----------------------------------------------------------------------------------
    @property
    def settings(self) -> WorkflowSettings:
        """A copy of the workflow's settings kept in the project.

        Change the copy and give it back with :meth:`set_settings`.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> settings = session.settings
        >>> settings.loop.rim = "off"
        >>> session.set_settings(settings)
        >>> session.settings.loop.rim
        'off'
        """
        return WorkflowSettings.from_dict(self.project.settings.get(SETTINGS_KEY))

    def set_settings(self, settings: WorkflowSettings) -> None:
        """Keep ``settings`` in the project (saved with it; not an undoable edit).

        Parameters
        ----------
        settings : WorkflowSettings
            The matcher, loop, quality and tracking settings every later match uses.
        """
        self.project.settings[SETTINGS_KEY] = settings.to_dict()

    # -- frames, views, components -------------------------------------------------------------
    @property
    def frames(self) -> list[int]:
        """The frame numbers, in order (a copy)."""
        return list(self.project.frames)

    @property
    def views(self):
        """The calibrated views (:class:`~fluorogui.core.projection.geometry.View`), one per camera."""
        return list(self.project.views)

    @property
    def n_views(self) -> int:
        return len(self.project.views)

    def has_frame(self, frame: int) -> bool:
        return frame in self.project.frames

    def index_of(self, frame: int) -> int:
        """Position of a frame number in the project's frame list (KeyError if absent)."""
        try:
            return self.project.frames.index(frame)
        except ValueError:
            raise KeyError(f"frame {frame} is not in the project") from None

    def neighbour(self, frame: int, step: int) -> int:
        """The frame ``step`` places before/after ``frame`` (clamped to the first/last)."""
        frames = self.project.frames
        i = min(max(self.index_of(frame) + step, 0), len(frames) - 1)
        return frames[i]

    def components(self) -> list[str]:
        """The components with a model, femoral first, then tibial, then any others."""
        names = [m.component for m in self.project.models]
        return sorted(names, key=lambda n: (COMPONENT_ORDER.index(n) if n in COMPONENT_ORDER else 99, n))

    def image_path(self, frame: int, view: int) -> Path | None:
        """The image file of a frame in a view (None when that camera has no image for it)."""
        if view >= len(self.project.sequences) or frame not in self.project.frames:
            return None
        paths = self.project.sequences[view].paths
        i = self.project.frames.index(frame)
        return paths[i] if i < len(paths) else None

    def image_paths(self, frame: int) -> list[Path | None]:
        return [self.image_path(frame, v) for v in range(self.n_views)]

    def image(self, frame: int, view: int) -> np.ndarray:
        """One image of a frame, distortion-corrected for its view (cached).

        Parameters
        ----------
        frame : int
            A frame number.
        view : int
            The view's index (0 for the first camera).

        Returns
        -------
        numpy.ndarray
            2-D float32 in [0, 1], indexed ``[v, u]``.

        Raises
        ------
        fluorogui.io.errors.InputError
            The file cannot be read, or the camera has no image for this frame.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.image(0, 1).shape
        (256, 256)
        """
        path = self.image_path(frame, view)
        if path is None:
            n = len(self.project.sequences[view].paths) if view < len(self.project.sequences) else 0
            raise InputError(f"view {view + 1}", f"no image for frame {frame} (this camera has {n} images)")
        with self._cache_lock:
            if path in self._images:
                self._images.move_to_end(path)
                return self._images[path]
        views = self.project.views
        image = read_view_image(path, views[view] if view < len(views) else None)
        with self._cache_lock:
            self._images[path] = image
            while len(self._images) > IMAGE_CACHE_FRAMES * max(1, self.n_views):
                self._images.popitem(last=False)
        return image

    def images(self, frame: int) -> list[np.ndarray]:
        """The images of a frame, one per view (see :meth:`image`).

        Raises
        ------
        fluorogui.io.errors.InputError
            An image cannot be read or is missing.
        """
        return [self.image(frame, v) for v in range(self.n_views)]

    def raw_mesh(self, component: str) -> tuple[np.ndarray, np.ndarray]:
        """Vertices and faces of a component's mesh in its local frame; raises InputError."""
        if component not in self._raw_meshes:
            entry = self.project.model(component)
            if entry is None:
                raise KeyError(component)
            self._raw_meshes[component] = read_model(entry.mesh_path, entry.local_frame)
        return self._raw_meshes[component]

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
        self._raw_meshes.pop(component, None)
        self._meshes.pop(component, None)
        self._notify(SessionEvent.MODEL, component)

    def mesh(self, component: str) -> PreparedMesh:
        """The component's mesh prepared for matching (cached).

        Parameters
        ----------
        component : str
            ``"femoral"``, ``"tibial"`` or another model's name.

        Returns
        -------
        fluorogui.core.projection.mesh.PreparedMesh
            Vertices (mm, the model's frame), faces, normals and edge adjacency.

        Raises
        ------
        fluorogui.io.errors.InputError
            The mesh file cannot be read or is not an implant-sized closed surface.
        KeyError
            The session has no such component.
        """
        if component not in self._meshes:
            self._meshes[component] = prepared_model(self.project.model(component).mesh_path,
                                                     *self.raw_mesh(component))
        return self._meshes[component]

    # -- poses ---------------------------------------------------------------------------------
    def pose_record(self, component: str, frame: int) -> PoseRecord | None:
        """The stored pose with its status, reason, review flag and match record, or None.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> record = session.pose_record("femoral", 0)
        >>> str(record.status), record.reviewed
        ('placed', False)
        """
        return self.project.poses.get((frame, component))

    def pose(self, component: str, frame: int) -> np.ndarray:
        """The component's pose in a frame, or the best stand-in for one.

        Its own stored pose; else the nearest earlier (then later) frame's; else a default
        that puts the model where the views' central rays meet (one view: on its central
        ray at 85 % of the source-intensifier distance).

        Parameters
        ----------
        component : str
        frame : int

        Returns
        -------
        numpy.ndarray
            ``(x, y, z, alpha, beta, gamma)`` in mm and degrees: ``X = R m + t`` with
            ``R = Ry(beta) Rz(gamma) Rx(alpha)``.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.pose("tibial", 0).round(1).tolist()
        [2.5, -4.9, -15.0, -1.2, 2.1, 4.2]
        """
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
        elif views:  # single plane: on the central ray, where a knee usually sits (~85% of the way)
            point = views[0].source + views[0].normal * SINGLE_PLANE_DEPTH * views[0].distance
        else:
            point = np.zeros(3)
        centroid = np.zeros(3)
        try:
            centroid = self.mesh(component).centroid
        except (InputError, KeyError):
            pass
        return np.concatenate([point - centroid, np.zeros(3)])

    # -- results -------------------------------------------------------------------------------
    def store(self, results: FrameResult | Iterable[FrameResult], text: str | None = None) -> None:
        """Put match or tracking results into the project as one undoable step.

        Each result's pose record (with its status and reason) and automatic outlines are
        stored; a reviewed outline is never replaced and an accepted pose never touched.
        Results marked ``kept`` are skipped. This is how the results of a job that ran
        elsewhere (:meth:`match_job`, :meth:`track_job`) come back.

        Parameters
        ----------
        results : FrameResult or iterable of FrameResult
        text : str, optional
            The step's name in the undo history (default: "Match ...").
        """
        results = [results] if isinstance(results, FrameResult) else list(results)
        todo = [r for r in results if not r.kept]
        if not todo:
            return
        label = text or ("Match " + ", ".join(sorted({r.component for r in todo})) +
                         (f" in frame {todo[0].frame}" if len({r.frame for r in todo}) == 1 else ""))
        self.history.begin_macro(label)
        try:
            for r in todo:
                existing = self.project.poses.get((r.frame, r.component))
                if existing is not None and existing.reviewed:
                    continue
                weights = r.outline_weights or []
                for view, points in enumerate(r.outlines or []):
                    key = (r.frame, view, r.component)
                    old = self.project.records.get(key)
                    if points is not None and (old is None or not old.reviewed):
                        # 1e-4 px is far below the edges' accuracy and keeps the file small
                        w = weights[view] if view < len(weights) else None
                        self.set_outline(key, np.round(points, 4), "Automatic outline", reviewed=False,
                                         weights=w)
                record = r.record()
                if record is not None:
                    self.set_record(r.component, r.frame, record, "Match")
                if r.rim_settled is not None and all(m is not None for m in r.rim_settled):
                    self._keep_rim_models(r.component, r.rim_settled)
        finally:
            self.history.end_macro()

    # -- progress of the work --------------------------------------------------------------------
    def frame_state(self, frame: int) -> FrameState:
        """How far the work on a frame has got (the timeline's colour).

        Returns
        -------
        FrameState
            ``NEEDS_REVIEW`` if any component needs review; ``REVIEWED`` if every
            component is matched and accepted; ``MATCHED`` if every one is matched;
            ``OUTLINED`` if any component has an outline or a pose in the frame (placed
            by hand, by *find* or from a file: the timeline's "outlined or placed");
            else ``EMPTY``.
        """
        names = self.components()
        if not names:
            return FrameState.EMPTY
        records = [self.project.poses.get((frame, c)) for c in names]
        if any(r is not None and r.needs_review for r in records):
            return FrameState.NEEDS_REVIEW
        if all(r is not None and r.is_matched for r in records):
            return FrameState.REVIEWED if all(r.reviewed for r in records) else FrameState.MATCHED
        if any(r is not None for r in records) or any(
                (frame, v, c) in self.project.records for v in range(self.n_views) for c in names):
            return FrameState.OUTLINED
        return FrameState.EMPTY

    def frame_states(self) -> list[FrameState]:
        return [self.frame_state(f) for f in self.project.frames]
