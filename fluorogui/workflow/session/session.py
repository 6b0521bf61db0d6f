"""The Qt-free session: one open project and everything done to it.

``Session`` is what the desktop app, the command line and scripts share (the pattern of
glue's Application or MNE's coreg under its GUI). It owns the project, its file and
saving (atomic, with a backup), the undo ``history`` and the listeners, and composes
plain parts, each given what it needs in its constructor:

* ``cache`` (``cache.py``): images, meshes, splines and default anatomical frames;
* ``reader`` (``reader.py``): frames by frame number (never by index), views, components,
  images, meshes, poses and their stand-ins, each frame's progress;
* ``edits`` (``edits.py``): every edit as an undoable ``Command`` on ``history`` (poses,
  placement, orientation presets, review flags, outlines, mesh files); the app's Qt undo
  stack only mirrors it;
* ``work`` (``work.py``): ``match``, ``find`` and ``track``, each also a job that runs in a
  worker thread or another process and returns results that ``store`` puts into the
  project on the caller's thread;
* ``knee`` (``knee.py``): the knee's side, anatomical frames and kinematics.

Session's methods hand over to these parts, so its public API is one place. Listeners
(``session.listeners``) hear every change as ``listener(event, what)``, the events and
what each carries listed in ``events.SessionEvent``.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterable, Iterator, Sequence

import numpy as np

from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.records import ImageSequence, ModelEntry, PoseRecord, Project
from fluorogui.io.project.document import journal_frames, load_project, save_project
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.session.cache import SessionCache
from fluorogui.workflow.session.edits import Edits
from fluorogui.workflow.session.events import SessionEvent
from fluorogui.workflow.session.history import CommandStack
from fluorogui.workflow.session.knee import Knee
from fluorogui.workflow.session.reader import FrameState, Reader
from fluorogui.workflow.session.work import Work
from fluorogui.workflow.settings import SETTINGS_KEY, WorkflowSettings

if TYPE_CHECKING:  # the parts' types, named in the signatures Session hands over
    from fluorogui.core.outlines.rim import RimModel
    from fluorogui.core.outlines.spline import OutlineSpline
    from fluorogui.core.records import OutlineRecord
    from fluorogui.core.search.find import Placement
    from fluorogui.workflow.session.knee import KneeRow
    from fluorogui.workflow.session.work import FindJob, MatchJob
    from fluorogui.workflow.tracking import TrackJob, TrackProgress


def _as(part_method):
    """Give a Session method that hands over to a part the part's docstring."""
    def adopt(method):
        method.__doc__ = part_method.__doc__
        return method
    return adopt


def _property_of(part: str, prop: property) -> property:
    """A read-only Session property that is a part's."""
    name = prop.fget.__name__
    return property(lambda self: getattr(getattr(self, part), name), doc=prop.__doc__)


class Session:
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
    history : fluorogui.workflow.session.history.CommandStack
        The undo history: ``history.undo()``, ``history.redo()``.
    listeners : list of callable
        Called as ``listener(event, what)`` on every change, ``event`` a
        :class:`~fluorogui.workflow.session.events.SessionEvent` (a ``str``: ``"pose"``,
        ``"outline"``, ``"knee"``, ``"model"``, ``"project"``, ``"saved"``), ``what`` as it
        lists.
    cache, reader, edits, work, knee
        The parts (``SessionCache``, ``Reader``, ``Edits``, ``Work``, ``Knee``) the methods
        hand over to; :meth:`replace_project` gives them the new project.

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
        self.dirty_on_disk = False  # frames in the project's journal, not yet in its file
        self._journaled_settings: str | None = None
        self._compose()

    def _compose(self) -> None:
        """The parts, on the current project (a new cache: nothing of another project is kept)."""
        common = {"project": self.project, "history": self.history}
        self.cache = SessionCache()
        self.reader = Reader(self.project, self.cache)
        self.edits = Edits(**common, cache=self.cache, reader=self.reader, notify=self._notify)
        self.knee = Knee(**common, cache=self.cache, reader=self.reader, notify=self._notify)
        self.work = Work(**common, reader=self.reader, edits=self.edits, storage=self)

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
        self._compose()
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
                        self.edits.set_outline(key, np.round(points, 4), "Automatic outline", reviewed=False,
                                         weights=w)
                record = r.record()
                if record is not None:
                    self.edits.set_record(r.component, r.frame, record, "Match")
                if r.rim_settled is not None and all(m is not None for m in r.rim_settled):
                    self.work.keep_rim_models(r.component, r.rim_settled)
        finally:
            self.history.end_macro()

    # -- frames, views, components, images, meshes, poses, progress (the reader) -----------------
    frames = _property_of("reader", Reader.frames)
    views = _property_of("reader", Reader.views)
    n_views = _property_of("reader", Reader.n_views)

    @_as(Reader.has_frame)
    def has_frame(self, frame: int) -> bool:
        return self.reader.has_frame(frame)

    @_as(Reader.index_of)
    def index_of(self, frame: int) -> int:
        return self.reader.index_of(frame)

    @_as(Reader.neighbour)
    def neighbour(self, frame: int, step: int) -> int:
        return self.reader.neighbour(frame, step)

    @_as(Reader.components)
    def components(self) -> list[str]:
        return self.reader.components()

    @_as(Reader.image_path)
    def image_path(self, frame: int, view: int) -> Path | None:
        return self.reader.image_path(frame, view)

    @_as(Reader.image_paths)
    def image_paths(self, frame: int) -> list[Path | None]:
        return self.reader.image_paths(frame)

    @_as(Reader.image)
    def image(self, frame: int, view: int) -> np.ndarray:
        return self.reader.image(frame, view)

    @_as(Reader.images)
    def images(self, frame: int) -> list[np.ndarray]:
        return self.reader.images(frame)

    @_as(Reader.raw_mesh)
    def raw_mesh(self, component: str) -> tuple[np.ndarray, np.ndarray]:
        return self.reader.raw_mesh(component)

    @_as(Reader.mesh)
    def mesh(self, component: str) -> PreparedMesh:
        return self.reader.mesh(component)

    @_as(Reader.pose_record)
    def pose_record(self, component: str, frame: int) -> PoseRecord | None:
        return self.reader.pose_record(component, frame)

    @_as(Reader.pose)
    def pose(self, component: str, frame: int) -> np.ndarray:
        return self.reader.pose(component, frame)

    @_as(Reader.default_pose)
    def default_pose(self, component: str) -> np.ndarray:
        return self.reader.default_pose(component)

    @_as(Reader.frame_state)
    def frame_state(self, frame: int) -> FrameState:
        return self.reader.frame_state(frame)

    @_as(Reader.frame_states)
    def frame_states(self) -> list[FrameState]:
        return self.reader.frame_states()

    # -- undoable edits (the edits) --------------------------------------------------------------
    @_as(Edits.set_pose)
    def set_pose(self, component: str, frame: int, pose, text: str = "Move model", *,
                 mergeable: bool = False) -> None:
        self.edits.set_pose(component, frame, pose, text, mergeable=mergeable)

    @_as(Edits.set_record)
    def set_record(self, component: str, frame: int, record: PoseRecord | None, text: str) -> None:
        self.edits.set_record(component, frame, record, text)

    @_as(Edits.set_reviewed)
    def set_reviewed(self, component: str, frame: int, reviewed: bool = True) -> None:
        self.edits.set_reviewed(component, frame, reviewed)

    @_as(Edits.place_at)
    def place_at(self, component: str, frame: int, pixels) -> float:
        return self.edits.place_at(component, frame, pixels)

    @_as(Edits.orient)
    def orient(self, component: str, frame: int, angles) -> None:
        self.edits.orient(component, frame, angles)

    @_as(Edits.relink_mesh)
    def relink_mesh(self, component: str, path) -> None:
        self.edits.relink_mesh(component, path)

    @_as(Edits.outline_record)
    def outline_record(self, key) -> OutlineRecord | None:
        return self.edits.outline_record(key)

    @_as(Edits.outline_points)
    def outline_points(self, key) -> np.ndarray | None:
        return self.edits.outline_points(key)

    @_as(Edits.set_outline)
    def set_outline(self, key, points, text: str = "Edit outline", *, reviewed: bool | None = True,
                    weights: np.ndarray | None = None) -> None:
        self.edits.set_outline(key, points, text, reviewed=reviewed, weights=weights)

    @_as(Edits.spline)
    def spline(self, key) -> OutlineSpline | None:
        return self.edits.spline(key)

    @_as(Edits.given_splines)
    def given_splines(self, component: str, frame: int) -> list[OutlineSpline | None] | None:
        return self.edits.given_splines(component, frame)

    # -- match, find, track (the work) -----------------------------------------------------------
    @_as(Work.rim_models)
    def rim_models(self) -> dict[str, list[RimModel]]:
        return self.work.rim_models()

    @_as(Work.matched_in)
    def matched_in(self, frame: int, components=None) -> list[str]:
        return self.work.matched_in(frame, components)

    @_as(Work.match_job)
    def match_job(self, frame: int, components=None) -> MatchJob:
        return self.work.match_job(frame, components)

    @_as(Work.match)
    def match(self, frame: int, components=None, live=None, cancel=None) -> list[FrameResult]:
        return self.work.match(frame, components, live, cancel)

    @_as(Work.find_job)
    def find_job(self, frame: int, components=None, replace: bool = False) -> FindJob:
        return self.work.find_job(frame, components, replace)

    @_as(Work.store_placements)
    def store_placements(self, placements: dict[str, Placement], replace: bool = False) -> None:
        self.work.store_placements(placements, replace)

    @_as(Work.find)
    def find(self, frame: int, components=None, *, progress=None, cancel=None,
             replace: bool = False) -> dict[str, Placement]:
        return self.work.find(frame, components, progress=progress, cancel=cancel, replace=replace)

    @_as(Work.track_job)
    def track_job(self, frames: Sequence[int] | None = None, components=None, *, redo: bool = False,
                  first: int | None = None, last: int | None = None, run: str | None = None) -> TrackJob:
        return self.work.track_job(frames, components, redo=redo, first=first, last=last, run=run)

    @_as(Work.track)
    def track(self, frames: Sequence[int] | None = None, components=None, *, redo: bool = False,
              progress: TrackProgress | None = None, cancel: Callable[[], bool] | None = None,
              autosave: bool = False, first: int | None = None, last: int | None = None,
              run: str | None = None, workers: int = 1) -> Iterator[FrameResult]:
        return self.work.track(frames, components, redo=redo, progress=progress, cancel=cancel, autosave=autosave,
                               first=first, last=last, run=run, workers=workers)

    # -- the knee (its side, anatomical frames, kinematics) --------------------------------------
    side = _property_of("knee", Knee.side)

    @_as(Knee.set_side)
    def set_side(self, side: str) -> None:
        self.knee.set_side(side)

    @_as(Knee.anatomical_frame)
    def anatomical_frame(self, component: str) -> np.ndarray:
        return self.knee.anatomical_frame(component)

    @_as(Knee.default_anatomical_frame)
    def default_anatomical_frame(self, component: str) -> np.ndarray:
        return self.knee.default_anatomical_frame(component)

    @_as(Knee.anatomical_frame_source)
    def anatomical_frame_source(self, component: str) -> str:
        return self.knee.anatomical_frame_source(component)

    @_as(Knee.set_anatomical_frame)
    def set_anatomical_frame(self, component: str, matrix) -> None:
        self.knee.set_anatomical_frame(component, matrix)

    @_as(Knee.reset_anatomical_frame)
    def reset_anatomical_frame(self, component: str) -> None:
        self.knee.reset_anatomical_frame(component)

    @_as(Knee.knee_rows)
    def knee_rows(self, frames=None) -> list[KneeRow]:
        return self.knee.knee_rows(frames)

    @_as(Knee.knee_at)
    def knee_at(self, frame: int) -> KneeRow:
        return self.knee.knee_at(frame)
