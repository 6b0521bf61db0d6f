"""The session's work: match a frame, find the implants, track frames.

Each comes twice: as a job (``match_job``, ``find_job``, ``track_job``) - a snapshot of
plain data taken on the caller's thread that can run anywhere (a worker thread, another
process) and returns results without touching the session - and as a method that runs
the job and stores its results (``match``, ``find``, ``track``). The desktop app runs the
jobs in its worker thread and stores the results on the GUI thread; the command line and
scripts call the methods. Same frame, same settings, same code: same pose. The images' rim
models that the jobs start from are kept in the project (``rim_models``).

``Work`` is a part of ``Session``: it is given the project, the history, the reader, the
edits and the session's ``Storage`` (storing and saving results), each named in its
constructor.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterator, Protocol, Sequence

import numpy as np

from fluorogui.core.outlines.rim import RimModel
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.records import Project
from fluorogui.core.search.find import Placement
from fluorogui.io.errors import InputError
from fluorogui.workflow.finding import find_in_frame, near_search
from fluorogui.workflow.framematch import ComponentInput, FrameMatcher
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.session.edits import Edits
from fluorogui.workflow.session.history import CommandStack
from fluorogui.workflow.session.reader import Reader
from fluorogui.workflow.settings import SETTINGS_KEY, WorkflowSettings
from fluorogui.workflow.tracking import TrackJob, TrackProgress, frames_between, read_frame_images

#: a tracking run with autosave saves the whole project this often (frames); in between it
#: appends each frame to the project's journal
FULL_SAVE_FRAMES = 50


@dataclass
class MatchJob:
    """Match components in one frame from their current poses (plain data, picklable)."""

    views: list[View]
    frame: int
    image_paths: list[Path | None]
    inputs: list[ComponentInput]
    fixed: dict = field(default_factory=dict)  # other components (mesh, pose) to mask
    settings: WorkflowSettings = field(default_factory=WorkflowSettings)
    rim: dict = field(default_factory=dict)  # component -> rim models per view judged before
    # the frame's images when the caller has read them already (``fluorogui match`` checks
    # them before any work); None: read from ``image_paths``
    images: list[np.ndarray] | None = None

    def run(self, live: Callable | None = None, cancel: Callable[[], bool] | None = None) -> list[FrameResult]:
        """The results, one per component. ``live(component, calls, objective_mm, pose)``
        follows every step of the matcher. Raises InputError for a missing image and
        ``Cancelled`` when ``cancel()`` turns true."""
        images = self.images
        if images is None:
            images = read_frame_images(self.frame, self.image_paths, len(self.views), views=self.views)
        matcher = FrameMatcher(self.views, self.settings, near_search(self.views, self.settings), live=live,
                              rim=self.rim)
        found = matcher.match_frame(self.frame, images, self.inputs, fixed=self.fixed, cancel=cancel)
        return [found[j.component] for j in self.inputs]


@dataclass
class FindJob:
    """Find components in one frame with no start (plain data)."""

    views: list[View]
    frame: int
    image_paths: list[Path | None]
    meshes: dict[str, PreparedMesh]

    def run(self, progress: Callable[[float, str], None] | None = None,
            cancel: Callable[[], bool] | None = None) -> dict[str, Placement]:
        """The placements by component; raises ``Cancelled`` when ``cancel()`` turns true."""
        if not self.meshes:
            return {}
        images = read_frame_images(self.frame, self.image_paths, len(self.views), views=self.views)
        return find_in_frame(self.frame, images, self.views, self.meshes, progress=progress, cancel=cancel)


#: ``project.settings`` key of the components' rim models (``Work.rim_models``)
RIM_KEY = "rim_models"


class Storage(Protocol):
    """What the work needs of the session that owns it: to store results and save them."""

    path: Path | None
    dirty_on_disk: bool

    def store(self, results, text: str | None = None) -> None: ...

    def save(self, path=None) -> Path: ...

    def save_frames(self, results) -> None: ...


class Work:
    """Match, find and track: the jobs, and the methods that run them and store the results.

    Parameters
    ----------
    project : fluorogui.core.records.Project
        Its poses, frames and settings (the workflow's settings and the rim models).
    history : CommandStack
        Placing found components is one step of it.
    reader : Reader
        Frames, views, components, image paths, meshes and the poses' stand-ins.
    edits : Edits
        The reviewed outlines matching uses as they are, and placing found components.
    storage : Storage
        Where results go (``store``) and how they are saved as tracking goes.
    """

    def __init__(self, *, project: Project, history: CommandStack, reader: Reader, edits: Edits,
                 storage: Storage) -> None:
        self.project = project
        self.history = history
        self.reader = reader
        self.edits = edits
        self.storage = storage

    @property
    def _settings(self) -> WorkflowSettings:
        return WorkflowSettings.from_dict(self.project.settings.get(SETTINGS_KEY))

    # -- the images' rim models -----------------------------------------------------------------
    def rim_models(self) -> dict[str, list[RimModel]]:
        """Each component's rim models per view, as kept in the project.

        The models (``core.outlines.rim.RimModel``: the metal's attenuation in 1/mm and the
        images' blur in px) are judged in a component's first matched frames and kept in
        ``project.settings["rim_models"]``, so that later matches and runs start from them
        instead of fitting them again.

        Returns
        -------
        dict of str to list of RimModel
            By component, one model per view; components not judged yet (or whose entry
            is damaged or has another number of views) are absent.
        """
        out = {}
        for component, models in (self.project.settings.get(RIM_KEY) or {}).items():
            try:
                out[component] = [RimModel(float(m["mu"]), float(m["sigma"])) for m in models]
            except (KeyError, TypeError, ValueError):
                continue  # a damaged entry is judged again
            if len(out[component]) != self.reader.n_views:
                del out[component]
        return out

    def keep_rim_models(self, component: str, models: list) -> None:
        kept = [{"mu": round(float(m.mu), 6), "sigma": round(float(m.sigma), 6)} for m in models]
        if self.project.settings.get(RIM_KEY, {}).get(component) != kept:
            self.project.settings.setdefault(RIM_KEY, {})[component] = kept

    # -- helpers ---------------------------------------------------------------------------------
    def _components(self, components) -> list[str]:
        names = self.reader.components()
        if components is None or components == "both" or components == "all":
            return names
        wanted = [components] if isinstance(components, str) else list(components)
        unknown = [c for c in wanted if c not in names]
        if unknown:
            raise KeyError(f"the project has no {', '.join(unknown)} component (it has {', '.join(names) or 'none'})")
        return [c for c in names if c in wanted]

    def _check_frame(self, frame: int) -> int:
        if frame not in self.project.frames:
            raise KeyError(f"frame {frame} is not in the project")
        return int(frame)

    def _residuals(self, component: str, before: int | None, window: int) -> list[float]:
        """Per-view residuals of the component's matched frames (up to ``before``)."""
        out = []
        for f in self.project.frames:
            if before is not None and f > before:
                break
            r = self.project.poses.get((f, component))
            if r is not None and r.is_matched and r.match is not None:
                out += list(r.match.per_view_mean_mm)
        return out[-2 * window:]

    @staticmethod
    def _typical(values: Sequence[float]) -> float | None:
        return float(np.median(values)) if len(values) >= 2 else None

    # -- match -------------------------------------------------------------------------------------
    def match_job(self, frame: int, components=None) -> MatchJob:
        """A job that matches components in ``frame``, to run anywhere (see :meth:`match`).

        A snapshot of plain data (views, image paths, meshes, start poses, reviewed
        outlines, the other components to mask, the settings) taken now; ``job.run()``
        returns the results without touching the session, so it can run in a worker thread
        or another process; :meth:`store` puts them in.

        Parameters
        ----------
        frame : int
        components : str or sequence of str, optional
            As for :meth:`match`.

        Returns
        -------
        MatchJob

        Raises
        ------
        KeyError
            The frame or a component is not in the project.
        fluorogui.io.errors.InputError
            A mesh cannot be read.
        """
        frame = self._check_frame(frame)
        names = self._components(components)
        settings = self._settings
        inputs = [ComponentInput(c, self.reader.mesh(c), self.reader.pose(c, frame), None,
                                 self.edits.given_splines(c, frame),
                                 self._typical(self._residuals(c, None, settings.tracking.typical_window)),
                                 predicted=False)
                  for c in names]
        fixed = {}
        for c in self.reader.components():
            if c not in names and (frame, c) in self.project.poses:
                try:
                    fixed[c] = (self.reader.mesh(c), self.reader.pose(c, frame))
                except InputError:
                    pass
        return MatchJob(self.reader.views, frame, self.reader.image_paths(frame), inputs, fixed, settings,
                        self.rim_models())

    def match(self, frame: int, components=None, live=None, cancel=None) -> list[FrameResult]:
        """Match components in one frame from their current poses, and store the results.

        Each component goes through the one per-frame matcher of the app, the command line
        and tracking: from :meth:`pose` (its own, else a neighbour's, else a default), its
        reviewed outlines as they are and the rest segmented automatically, the other
        components masked where they overlap, every quality check, and recovery from other
        starts when a check fails. The results are stored as one undoable step.

        Parameters
        ----------
        frame : int
            A frame number.
        components : str or sequence of str, optional
            ``"femoral"``, ``"tibial"``, a list of them, or ``"both"``; all by default.
        live : callable, optional
            ``live(component, calls, objective_mm, pose)`` after every step of the
            optimiser (the app's live overlay).
        cancel : callable, optional
            Polled during the work; when it returns True the match stops.

        Returns
        -------
        list of FrameResult
            One per component, in the session's component order.

        Raises
        ------
        fluorogui.core.cancel.Cancelled
            ``cancel()`` turned true; nothing is stored.
        fluorogui.io.errors.InputError
            An image or mesh is missing or unreadable.
        KeyError
            The frame or a component is not in the project.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> result, = session.match(0, "femoral")
        >>> result.component, str(result.status)
        ('femoral', 'matched')
        >>> truth = session.project.settings["demo_truth"]["0"]["femoral"]  # the demo knows
        >>> max(abs(a - b) for a, b in zip(result.pose, truth)) < 0.25      # mm and degrees
        True
        >>> session.history.undo()                  # the match was one undoable step
        """
        results = self.match_job(frame, components).run(live, cancel)
        self.storage.store(results)
        return results

    # -- find --------------------------------------------------------------------------------------
    def matched_in(self, frame: int, components=None) -> list[str]:
        """The components whose pose in ``frame`` is matched or accepted: what *find
        implants* and imported poses keep unless told to replace them.

        Parameters
        ----------
        frame : int
        components : str or sequence of str, optional
            As for :meth:`match`; all by default.
        """
        return [c for c in self._components(components)
                if (record := self.reader.pose_record(c, frame)) is not None and record.is_matched]

    def find_job(self, frame: int, components=None, replace: bool = False) -> FindJob:
        """A job that finds components in ``frame`` with no start, to run anywhere.

        ``job.run()`` returns the placements (see :meth:`find`) without touching the
        session; :meth:`store_placements` puts the confident ones in. Components whose pose
        is matched or accepted there (:meth:`matched_in`) are left out unless ``replace``.
        """
        frame = self._check_frame(frame)
        kept = [] if replace else self.matched_in(frame, components)
        meshes = {c: self.reader.mesh(c) for c in self._components(components) if c not in kept}
        return FindJob(self.reader.views, frame, self.reader.image_paths(frame), meshes)

    def store_placements(self, placements: dict[str, Placement], replace: bool = False) -> None:
        """Put the confidently found components at their poses (status ``placed``), as one
        undoable step; placements that are not ``found`` are left out, and so are those of
        components matched or accepted in their frame meanwhile, unless ``replace``.

        Parameters
        ----------
        placements : dict of str to Placement
            What :meth:`find` or a find job returned.
        replace : bool, optional
            Replace matched and accepted poses too.
        """
        found = [p for p in placements.values() if p.found and p.pose is not None
                 and (replace or p.component not in self.matched_in(p.frame, p.component))]
        if not found:
            return
        self.history.begin_macro("Find implants")
        try:
            for p in found:
                self.edits.set_pose(p.component, p.frame, p.pose, text=f"Find {p.component}")
        finally:
            self.history.end_macro()

    def find(self, frame: int, components=None, *, progress=None, cancel=None,
             replace: bool = False) -> dict[str, Placement]:
        """Find the components in a frame with no start pose (*find implants*).

        Only confident placements are stored (status ``placed``, one undoable step); the
        others say why in their ``reason``. A component whose pose in the frame is matched
        or accepted keeps it and is not searched for (:meth:`matched_in` lists them)
        unless ``replace``. Needs two views.

        Parameters
        ----------
        frame : int
        components : str or sequence of str, optional
            As for :meth:`match`; all by default.
        progress : callable, optional
            ``progress(fraction, text)`` as the search goes.
        cancel : callable, optional
            Polled during the search.
        replace : bool, optional
            Search for matched and accepted components too, and replace their poses.

        Returns
        -------
        dict of str to Placement
            The placement of every component searched for, found or not.

        Raises
        ------
        fluorogui.core.cancel.Cancelled
            ``cancel()`` turned true; nothing is stored.
        ValueError
            The session does not have two views.

        See Also
        --------
        fluorogui.core.search.find.find_components : The search itself.
        """
        placements = self.find_job(frame, components, replace).run(progress, cancel)
        self.store_placements(placements, replace)
        return placements

    # -- track -------------------------------------------------------------------------------------
    def track_job(self, frames: Sequence[int] | None = None, components=None, *, redo: bool = False,
                  first: int | None = None, last: int | None = None, run: str | None = None) -> TrackJob:
        """A tracking job, to run anywhere (see :meth:`track` for the parameters).

        A snapshot of everything tracking needs; ``job.run(progress, cancel)`` yields
        results per frame without touching the session, so the app runs it in its worker
        thread and ``fluorogui batch`` in Dask workers. Starts from the nearest matched frame
        at or before the first; where there is none, from a pose placed in the first frame,
        else it searches (*find implants*). Accepted poses are kept; with ``redo`` False, so
        are poses already matched; with ``run``, so are poses this same run (a retried batch
        task) already matched, even with ``redo``.

        Returns
        -------
        fluorogui.workflow.tracking.TrackJob
        """
        names = self._components(components)
        if frames is None:
            frames = frames_between(self.project.frames, first, last)
        frames = [self._check_frame(f) for f in frames]
        settings = self._settings
        window = settings.tracking.typical_window
        start_frame = frames[0] if frames else None
        anchors, starts, residuals = {}, {}, {}
        for c in names:
            before = [f for f in self.project.frames if start_frame is not None and f <= start_frame]
            matched = [(f, self.project.poses[(f, c)].pose.copy()) for f in before
                       if (f, c) in self.project.poses and self.project.poses[(f, c)].is_matched]
            if redo and matched and matched[-1][0] == start_frame and not self.project.poses[(start_frame, c)].reviewed:
                matched = matched[:-1]  # the first frame is matched again
            anchors[c] = matched[-2:]
            residuals[c] = self._residuals(c, start_frame, window)
            record = self.project.poses.get((start_frame, c)) if start_frame is not None else None
            if not matched and record is not None:
                starts[c] = record.pose.copy()  # placed by hand or by find implants
        keep, given = {}, {}
        for f in frames:
            for c in names:
                record = self.project.poses.get((f, c))
                same_run = (run is not None and record is not None and record.match is not None
                            and record.match.settings.get("run") == run)
                if record is not None and (record.reviewed or same_run or (not redo and record.is_matched)):
                    keep[(f, c)] = record
                g = self.edits.given_splines(c, f)
                if g is not None:
                    given[(f, c)] = g
        meshes = {c: self.reader.mesh(c) for c in names}
        paths = {f: self.reader.image_paths(f) for f in frames}
        counts = [len(seq.paths) for seq in self.project.sequences]
        return TrackJob(self.reader.views, meshes, frames, paths, names, settings, anchors, keep, given, residuals,
                        starts, image_counts=counts, rim=self.rim_models())

    def track(self, frames: Sequence[int] | None = None, components=None, *, redo: bool = False,
              progress: TrackProgress | None = None, cancel: Callable[[], bool] | None = None,
              autosave: bool = False, first: int | None = None, last: int | None = None,
              run: str | None = None, workers: int = 1) -> Iterator[FrameResult]:
        """Track components through frames, storing and yielding every result.

        Starts from the nearest matched frame at or before the first; where there is none,
        from a pose placed in the first frame, else it searches (*find implants*). Each frame
        is predicted from the last matched ones, matched with the other components masked,
        checked, and recovered from other starts when a check fails; what still fails is
        flagged (``needs_review`` or ``failed``) and tracking goes on. Tracking goes both
        ways: a component's failed frames are held back until it matches again, then tracked
        backward from there (the better result of the two directions is kept), and frames
        before the first one found are tracked back to the start; results still come out
        once per frame and component, in frame order. Accepted poses are kept, and so are
        matched ones unless ``redo``, so a stopped run resumes where it stopped. Each frame
        is stored as one undoable step as it finishes.

        Parameters
        ----------
        frames : sequence of int, optional
            The frame numbers to track, in order; default ``first`` .. ``last``.
        components : str or sequence of str, optional
            As for :meth:`match`; all by default.
        redo : bool, optional
            Match again frames already matched (accepted ones are still kept).
        progress : callable, optional
            ``progress(done, total, frame, text)`` after every frame.
        cancel : callable, optional
            Polled during the work; tracking stops at the next check.
        autosave : bool, optional
            Save every frame as it is stored: appended to the project's journal
            (:meth:`save_frames`), with the whole project saved every ``FULL_SAVE_FRAMES``
            frames and at the end, so a killed run loses at most the frame in progress.
        first, last : int, optional
            The first and last frame numbers (both included) when ``frames`` is not given;
            default the project's first and last.
        run : str, optional
            Names this run in the stored match records (a retried batch task keeps the
            frames its run already matched).
        workers : int, optional
            With more than 1, the frames are cut into that many consecutive runs tracked
            in parallel processes (every run after the first starts by finding the
            implants); results then arrive frame by frame but not in frame order.

        Yields
        ------
        FrameResult
            One per frame and component, as each frame finishes.

        Raises
        ------
        fluorogui.core.cancel.Cancelled
            ``cancel()`` turned true; the frames finished before stay stored.
        KeyError
            A frame or component is not in the project.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> results = list(session.track(components="femoral"))
        >>> [(r.frame, str(r.status)) for r in results]
        [(0, 'matched'), (1, 'matched')]
        >>> session.frame_state(1).name
        'OUTLINED'
        """
        job = self.track_job(frames, components, redo=redo, first=first, last=last, run=run)
        if workers > 1 and len(job.frames) >= 4:
            from fluorogui.workflow.tracking import run_parallel

            stream = run_parallel(job.split(workers), cancel)
        else:
            from fluorogui.workflow.tracking import by_frame

            stream = by_frame(job.run(progress, cancel), len(job.components))
        for done, results in enumerate(stream, start=1):
            frame = results[0].frame
            if run is not None:
                for r in results:
                    if r.match is not None:
                        r.match = replace(r.match, settings=dict(r.match.settings, run=run))
            self.storage.store(results, f"Track frame {frame}")
            if autosave and self.storage.path is not None and any(not r.kept for r in results):
                if done % FULL_SAVE_FRAMES == 0:
                    self.storage.save()
                else:
                    self.storage.save_frames(results)
            if workers > 1 and progress is not None:
                progress(done, len(job.frames), frame, f"frame {frame} done")
            yield from results
        if autosave and self.storage.path is not None and self.storage.dirty_on_disk:
            self.storage.save()
