"""Tracking components through frames: a generator of per-frame results that never lies.

``TrackJob`` is a snapshot of everything tracking needs (views, meshes, image files,
reviewed outlines, the poses to start from and to keep), taken from a session on the
caller's thread; ``run`` can then go on in a worker thread or another process. For each
frame it predicts every component from the frames matched so far (``MotionModel``),
matches all components together with each other's projections masked
(``FrameMatcher``), checks every result and recovers what fails (other starts, a search
near the prediction; across a jump of several frames, near where the component's image
from its last matched frame lies now: ``core.search.relocate``). A frame that still fails
is ``needs_review`` (or ``failed`` when no outline could be traced or an image is missing)
and tracking goes on: the prediction then
comes from the last frames that did match. A component with nothing to start from is
searched for (*find implants*) in the frame, again in every following frame until it is
found.

Tracking goes both ways: frames where a component failed are held back until it matches
again in a later frame, then tracked backward from there (``_fill_back``) - every gap
between matched frames is filled from both sides and the better result wins, and the
frames before the first one found are tracked back to the start. Results still come out
once per frame and component, in frame order (a held frame as soon as nothing before it
waits).

Accepted poses, and on a resumed run poses already matched, are kept as they are
(``kept``) and serve as the motion's anchors.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from fluorogui.core.cancel import check_cancel
from fluorogui.core.outlines.spline import OutlineSpline
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.projection.pose import angles_from_matrix, rotation_matrix
from fluorogui.core.records import PoseRecord
from fluorogui.core.search.relocate import relocated_centroid, with_centroid
from fluorogui.core.status import Status
from fluorogui.core.threads import each_view, is_view_thread_name, set_threads
from fluorogui.io.corrections import read_view_image
from fluorogui.io.errors import InputError
from fluorogui.workflow.finding import find_in_frame, near_search
from fluorogui.workflow.framematch import NEAR_FIRST_GAP, ComponentInput, FrameMatcher, better_result
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.settings import WorkflowSettings

#: progress(done, total, frame, text)
TrackProgress = Callable[[int, int, int, str], None]


@dataclass
class TrackJob:
    """What tracking frames needs, captured from a session (plain data, picklable)."""

    views: list[View]
    meshes: dict[str, PreparedMesh]
    frames: list[int]
    image_paths: dict[int, list[Path | None]]
    components: list[str]
    settings: WorkflowSettings
    anchors: dict[str, list[tuple[int, np.ndarray]]] = field(default_factory=dict)  # matched poses before
    keep: dict[tuple[int, str], PoseRecord] = field(default_factory=dict)  # (frame, component) left as is
    given: dict[tuple[int, str], list[OutlineSpline | None]] = field(default_factory=dict)  # reviewed outlines
    residuals: dict[str, list[float]] = field(default_factory=dict)  # per-view residuals of matched frames
    starts: dict[str, np.ndarray] = field(default_factory=dict)  # start poses for components without anchors
    find: bool = True  # search for components with no anchor and no start
    image_counts: list[int] = field(default_factory=list)  # images per camera, for messages
    rim: dict = field(default_factory=dict)  # component -> rim models per view judged before (the project's)
    # the latest frames' images (frame -> images): a jump's relocation compares the last matched one's
    _recent: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def run(self, progress: TrackProgress | None = None,
            cancel: Callable[[], bool] | None = None) -> Iterator[FrameResult]:
        """Yield one FrameResult per frame and component, frame by frame; raises
        ``Cancelled`` when ``cancel()`` turns true (the frame in progress is not yielded,
        the frames before it were)."""
        s = self.settings
        matcher = FrameMatcher(self.views, s, near_search(self.views, s), rim=self.rim)
        motion = {c: MotionModel(self.meshes[c].centroid) for c in self.components}
        for c, poses in self.anchors.items():
            for frame, pose in poses:
                motion[c].add(frame, pose)
        residuals = {c: list(self.residuals.get(c, [])) for c in self.components}
        starts = {c: np.asarray(p, float) for c, p in self.starts.items()}
        total = len(self.frames)
        t0 = time.perf_counter()
        held: list[tuple[int, dict[str, FrameResult]]] = []  # frames not yielded yet, in order
        waiting: dict[str, list[int]] = {c: [] for c in self.components}  # failed frames, per component
        for done, frame in enumerate(self.frames):
            check_cancel(cancel)
            results = self._frame(frame, matcher, motion, residuals, starts=starts, cancel=cancel)
            held.append((frame, results))
            for c in self.components:
                if self._is_anchor(frame, results[c]):
                    self._anchor(c, results[c], motion, residuals)
                    if waiting[c]:  # it matches again: track back into its gap
                        mended = self._fill_back(c, frame, waiting[c], dict(held), matcher=matcher, motion=motion,
                                                 residuals=residuals,
                                                 cancel=cancel)
                        waiting[c] = []
                        for f, o in mended:  # others matched once it was masked at its new pose there
                            if f in waiting.get(o, []):
                                waiting[o].remove(f)
                elif not results[c].kept:
                    waiting[c].append(frame)
            while held and not any(held[0][0] in frames for frames in waiting.values()):
                _, out = held.pop(0)
                yield from (out[c] for c in self.components)
            if progress is not None:
                progress(done + 1, total, frame, f"frame {frame} done ({time.perf_counter() - t0:.1f} s)")
        for _, out in held:  # gaps no later match closes: as tracked forward
            yield from (out[c] for c in self.components)

    def split(self, parts: int) -> list["TrackJob"]:
        """The job as ``parts`` jobs over consecutive runs of frames, to run in parallel. The
        first keeps the start; each later one starts from an accepted (or, when resuming,
        matched) pose in its first frames if it has one, else it finds the implants in its
        first frame - it cannot wait for the frames before it."""
        parts = max(1, min(int(parts), len(self.frames) // 2 or 1))
        bounds = np.linspace(0, len(self.frames), parts + 1).round().astype(int)
        jobs = []
        for k in range(parts):
            frames = self.frames[bounds[k]:bounds[k + 1]]
            job = replace(self, frames=frames, image_paths={f: self.image_paths[f] for f in frames})
            if k > 0:
                job.anchors = {c: [] for c in self.components}
                job.starts = {}
            jobs.append(job)
        return jobs

    # -- one frame -----------------------------------------------------------------------------
    def _kept_is_matched(self, frame: int, component: str) -> bool:
        record = self.keep.get((frame, component))
        return record is not None and record.is_matched

    def _is_anchor(self, frame: int, r: FrameResult) -> bool:
        """A result the motion may go by: matched, or kept as accepted / already matched."""
        kept_matched = r.kept and r.pose is not None and self._kept_is_matched(frame, r.component)
        return r.status == Status.MATCHED or kept_matched

    def _anchor(self, c: str, r: FrameResult, motion, residuals) -> None:
        motion[c].add(r.frame, r.pose)
        if r.match is not None and not r.kept:
            window = 2 * self.settings.tracking.typical_window
            residuals[c] = (residuals[c] + list(r.match.per_view_mean_mm))[-window:]

    def _fill_back(self, c: str, frame: int, gap: list[int], results: dict, *, matcher, motion, residuals,
                   cancel) -> list[tuple[int, str]]:
        """Track ``c`` backward from its match in ``frame`` through the ``gap`` frames before
        it (where it failed), each predicted from the frames after it, with the other
        components masked at their poses there. A better result replaces the one tracked
        forward (in ``results``, frame -> component -> result); the first frame that does
        not match backward either ends the fill (the forward result stands from there). In
        each frame it now matches, the other components left flagged are judged again
        (``_judge_again``); returns the (frame, component) pairs that then matched."""
        mended: list[tuple[int, str]] = []
        back = MotionModel(self.meshes[c].centroid)
        later = [f for f in motion[c].frames if f >= frame]
        for f in later[:2]:
            back.add(f, motion[c].poses[motion[c].frames.index(f)])
        for f in sorted(gap, reverse=True):
            check_cancel(cancel)
            try:
                images = self._images(f)
            except InputError:
                continue  # the forward result says what is missing
            others = {o: (self.meshes[o], r.pose) for o, r in results[f].items()
                      if o != c and r.pose is not None and r.status != Status.FAILED}
            typical = float(np.median(residuals[c])) if len(residuals[c]) >= 2 else None
            job = ComponentInput(c, self.meshes[c], back.predict(f), back.poses[0].copy(), self.given.get((f, c)),
                                 typical, None, back.frames[0] - f, probe=False, search=False)
            found = matcher.match_frame(f, images, [job], fixed=others, cancel=cancel)[c]
            if not better_result(found, results[f][c]):
                if found.status != Status.MATCHED:
                    break
                continue
            found.recovered = "tracked back" + (f" ({found.recovered})" if found.recovered else "")
            results[f][c] = found
            if found.status != Status.MATCHED:
                break
            back.add(f, found.pose)
            self._anchor(c, found, motion, residuals)
            mended += [(f, o) for o in self._judge_again(f, c, images, results[f], matcher=matcher, motion=motion,
                                                         residuals=residuals,
                                                         cancel=cancel)]
        return mended

    def _judge_again(self, f: int, c: str, images, results: dict, *, matcher, motion, residuals,
                     cancel) -> list[str]:
        """``c`` now matches in frame ``f`` (tracked back): the other components left flagged
        there were masked with its old pose (or none), so they are matched again with it
        masked at its new one, from their own results; a better result replaces theirs.
        Returns the components that now match."""
        matched = []
        for o, earlier in list(results.items()):
            if o == c or earlier.kept or earlier.status == Status.MATCHED:
                continue
            others = {k: (self.meshes[k], r.pose) for k, r in results.items()
                      if k != o and r.pose is not None and r.status != Status.FAILED}
            start = motion[o].predict(f)
            start = earlier.pose if start is None else start
            if start is None:
                continue
            typical = float(np.median(residuals[o])) if len(residuals[o]) >= 2 else None
            job = ComponentInput(o, self.meshes[o], np.asarray(start, float), motion[o].last(before=f),
                                 self.given.get((f, o)), typical, None, 1, probe=False,
                                 first=earlier.pose if earlier.pose is not None else None)
            again = matcher.match_frame(f, images, [job], fixed=others, cancel=cancel)[o]
            if better_result(again, earlier):
                again.recovered = "judged again" + (f" ({again.recovered})" if again.recovered else "")
                again.seconds += earlier.seconds
                results[o] = again
                if again.status == Status.MATCHED:
                    self._anchor(o, again, motion, residuals)
                    matched.append(o)
        return matched

    def _frame(self, frame, matcher, motion, residuals, *, starts, cancel) -> dict[str, FrameResult]:
        t0 = time.perf_counter()
        results: dict[str, FrameResult] = {}
        todo = []
        for c in self.components:
            kept = self.keep.get((frame, c))
            if kept is not None:
                results[c] = FrameResult(frame, c, kept.pose.copy(), kept.status, kept.reason, kept=True)
            else:
                todo.append(c)
        if not todo:
            return results
        try:
            images = self._images(frame)
        except InputError as exc:
            for c in todo:
                results[c] = FrameResult(frame, c, self._predicted(c, frame, motion, starts), Status.FAILED,
                                         f"{exc.path}: {exc.problem}", seconds=time.perf_counter() - t0,
                                         failed=["image"])
            return results
        # components with nothing to start from: find them in this frame
        lost = [c for c in todo if len(motion[c]) == 0 and c not in starts]
        found_here: set[str] = set()
        if lost and self.find:
            placements = find_in_frame(frame, images, self.views, {c: self.meshes[c] for c in lost}, cancel=cancel)
            for c in lost:
                p = placements[c]
                if p.found and p.pose is not None:
                    starts[c] = p.pose
                    found_here.add(c)
                else:
                    results[c] = FrameResult(frame, c, p.pose, Status.FAILED, "find implants could not place it: "
                                             f"{p.reason}", seconds=time.perf_counter() - t0, failed=["find"])
            todo = [c for c in todo if c not in results]
        fixed = {c: (self.meshes[c], r.pose) for c, r in results.items() if r.kept and r.pose is not None}
        # a component find could not place is still masked where its closest miss lies: on
        # overlapping views the other's outline behind it is not there to count as missing
        fixed.update({c: (self.meshes[c], results[c].pose) for c in lost
                      if c in results and results[c].pose is not None and "find" in results[c].failed})
        jobs = [self._input(c, frame, motion, residuals, starts=starts, probe=c not in found_here, images=images)
                for c in todo]
        found = matcher.match_frame(frame, images, jobs, fixed=fixed, cancel=cancel)
        for c in todo:
            results[c] = found[c]
            starts.pop(c, None)  # a start is used once; afterwards the motion predicts
        return results

    def _images(self, frame: int) -> list[np.ndarray]:
        """The frame's images; the latest three frames' are kept (a jump compares the last matched one's)."""
        if frame not in self._recent:
            self._recent[frame] = read_frame_images(frame, self.image_paths.get(frame, []), len(self.views),
                                                    counts=self.image_counts, views=self.views)
            while len(self._recent) > 3:
                self._recent.pop(next(iter(self._recent)))
        return self._recent[frame]

    def _predicted(self, c, frame, motion, starts) -> np.ndarray | None:
        p = motion[c].predict(frame)
        return p if p is not None else starts.get(c)

    def _input(self, c, frame, motion, residuals, *, starts, probe: bool = True, images=None) -> ComponentInput:
        m = motion[c]
        start = starts.get(c) if len(m) == 0 else m.predict(frame)
        last = m.last(before=frame)
        typical = None
        if len(residuals[c]) >= 2:
            typical = float(np.median(residuals[c]))
        before = [f for f in m.frames if f < frame]
        gap = frame - before[-1] if before else 1
        # a matched frame before tells orientations apart (a flip would be a jump from it), and
        # find implants checks its own placements for one; a start placed by hand is probed
        located = None
        if images is not None and before and gap > NEAR_FIRST_GAP:
            located = self._located(c, before[-1], last, start, images=images)
        return ComponentInput(c, self.meshes[c], np.asarray(start, float), last, self.given.get((frame, c)),
                              typical, _recent_axis(m, frame), gap, probe=probe and not before, located=located)

    def _located(self, c: str, last_frame: int, last_pose, start, *, images) -> np.ndarray | None:
        """The prediction ``start`` moved to where ``c``'s image in ``last_frame`` (matched
        at ``last_pose``) lies in ``images``; None when the images do not tell."""
        try:
            earlier = self._images(last_frame)
        except InputError:
            return None
        centroid = relocated_centroid(earlier, images, self.views, self.meshes[c], pose=last_pose)
        return None if centroid is None else with_centroid(start, self.meshes[c], centroid)


def read_frame_images(frame: int, paths: Sequence[Path | None], n_views: int,
                      *, counts: Sequence[int] = (), views: Sequence | None = None) -> list[np.ndarray]:
    """The images of a frame, one per view (corrected for each view's distortion when
    ``views`` are given), to be matched; raises InputError naming the view (and how many
    images its camera has) when one is missing, or the file when it cannot be read or is
    blank (``io.images.check_not_blank``)."""
    paths = list(paths) + [None] * (n_views - len(paths))
    for view, path in enumerate(paths):
        if path is None:
            count = f" (this camera has {counts[view]} images)" if view < len(counts) else ""
            raise InputError(f"view {view + 1}", f"no image for frame {frame}{count}")
    return each_view(lambda k: read_view_image(paths[k], views[k] if views is not None and k < len(views) else None,
                                               for_matching=True), range(len(paths)))


def _recent_axis(m: MotionModel, frame: int) -> np.ndarray | None:
    """Unit axis (world) of the rotation between the two latest matched frames before ``frame``."""
    idx = [i for i, f in enumerate(m.frames) if f < frame]
    if len(idx) < 2:
        return None
    p1, p2 = m.poses[idx[-2]], m.poses[idx[-1]]
    w = Rotation.from_matrix(rotation_matrix(*p2[3:]) @ rotation_matrix(*p1[3:]).T).as_rotvec()
    n = np.linalg.norm(w)
    return w / n if n > 1e-6 else None


def frames_between(frames: Sequence[int], first: int | None, last: int | None) -> list[int]:
    """The project's frames from ``first`` to ``last``, both included (None: open end)."""
    return [f for f in frames if (first is None or f >= first) and (last is None or f <= last)]


def select_frames(spec: str | None, frames: Sequence[int]) -> list[int]:
    """The frames named by ``spec``: "A:B" (both ends included, either may be left out),
    "N", or a comma-separated list of these; None or "" means all. Raises ValueError
    ("SPEC: what is wrong")."""
    frames = list(frames)
    if spec is None or str(spec).strip() in ("", ":"):
        return frames
    chosen: list[int] = []
    for item in str(spec).split(","):
        item = item.strip()
        try:
            if ":" in item:
                a, b = item.split(":", 1)
                lo = int(a) if a.strip() else None
                hi = int(b) if b.strip() else None
            else:
                lo = hi = int(item)
        except ValueError:
            raise ValueError(f"{spec}: use A:B, N or a comma-separated list of these") from None
        if lo is not None and hi is not None and hi < lo:
            raise ValueError(f"{spec}: {item} ends before it starts")
        if ":" not in item and lo not in frames:
            raise ValueError(f"{spec}: frame {lo} is not in the project")
        chosen += frames_between(frames, lo, hi)
    out = sorted(set(chosen))
    if not out:
        raise ValueError(f"{spec}: no project frame lies in that range")
    return out


def by_frame(results: Iterator[FrameResult], n_components: int) -> Iterator[list[FrameResult]]:
    """Group a job's results (a frame's components come one after another) into frames."""
    pending: list[FrameResult] = []
    for result in results:
        pending.append(result)
        if len(pending) == n_components:
            yield pending
            pending = []


def run_parallel(jobs: Sequence[TrackJob], cancel: Callable[[], bool] | None = None) -> Iterator[list[FrameResult]]:
    """Run jobs in worker processes (one each), yielding each frame's results (a list) as
    soon as a worker sends them; frames of different jobs interleave. Uses the standard
    library's process pool and a manager queue."""
    import multiprocessing
    import threading
    from concurrent.futures import ProcessPoolExecutor

    # fork starts fast and needs no "if __name__ == '__main__'" in the caller's script, but is
    # unsafe beside other threads (the GUI, Dask): spawn then (the per-view helpers, idle
    # between calls, are not copied and a child makes its own: ``core.threads``)
    methods = multiprocessing.get_all_start_methods()
    alone = all(t is threading.current_thread() or is_view_thread_name(t.name) for t in threading.enumerate())
    context = multiprocessing.get_context("fork" if alone and "fork" in methods else "spawn")
    with context.Manager() as manager, ProcessPoolExecutor(len(jobs), mp_context=context) as pool:
        queue, stop = manager.Queue(), manager.Event()
        futures = [pool.submit(_run_job, job, queue, stop) for job in jobs]
        running = len(jobs)
        while running:
            if cancel is not None and cancel():
                stop.set()
            try:
                item = queue.get(timeout=0.2)
            except Exception:  # noqa: BLE001 - queue.Empty from the manager: look at the workers again
                for f in futures:
                    if f.done() and f.exception() is not None:
                        stop.set()
                        raise f.exception() from None
                continue
            if item is None:
                running -= 1
            else:
                yield item
        for f in futures:
            f.result()  # re-raise a worker's error


def _run_job(job: TrackJob, queue, stop) -> None:
    set_threads(1)  # the worker processes keep the cores busy already
    try:
        for frame in by_frame(job.run(cancel=stop.is_set), len(job.components)):
            queue.put(frame)
    finally:
        queue.put(None)


# -- predicting the next frame -------------------------------------------------------------
# Predicting a component's pose in the next frame from the frames matched so far.
#
# Constant velocity about the model centroid: the centroid moves and the body turns at the
# rate of the last two matched frames (per frame number, so gaps in the frame numbers are
# handled), extrapolated at most twice as far as those two frames lie apart so that a
# long gap does not fling the prediction away. With one matched frame the prediction is
# that frame's pose. A frame before every matched one is predicted backward the same way,
# from the two earliest matched frames (tracking back to the start).
class MotionModel:
    """Matched poses of one component by frame number, and predictions from them."""

    def __init__(self, centroid: np.ndarray) -> None:
        self.centroid = np.asarray(centroid, dtype=float)
        self.frames: list[int] = []
        self.poses: list[np.ndarray] = []

    def add(self, frame: int, pose) -> None:
        """Record a matched (or accepted) pose; keeps the frames sorted."""
        frame = int(frame)
        if frame in self.frames:
            i = self.frames.index(frame)
            self.poses[i] = np.asarray(pose, dtype=float).copy()
            return
        i = int(np.searchsorted(self.frames, frame))
        self.frames.insert(i, frame)
        self.poses.insert(i, np.asarray(pose, dtype=float).copy())

    def __len__(self) -> int:
        return len(self.frames)

    def last(self, before: int | None = None) -> np.ndarray | None:
        """The latest recorded pose (before frame ``before`` when given)."""
        idx = [i for i, f in enumerate(self.frames) if before is None or f < before]
        return self.poses[idx[-1]].copy() if idx else None

    def predict(self, frame: int) -> np.ndarray | None:
        """The pose expected at ``frame`` from the two latest recorded frames before it, or,
        when none is before it, from the two earliest after it (backward)."""
        idx = [i for i, f in enumerate(self.frames) if f < frame]
        if not idx:
            idx = [i for i, f in enumerate(self.frames) if f > frame][:2][::-1]  # nearest last
        if not idx:
            return None
        if len(idx) == 1:
            return self.poses[idx[-1]].copy()
        (f1, p1), (f2, p2) = [(self.frames[i], self.poses[i]) for i in idx[-2:]]
        steps = min(abs(frame - f2), 2 * abs(f2 - f1)) / abs(f2 - f1)
        R1, R2 = rotation_matrix(*p1[3:]), rotation_matrix(*p2[3:])
        c1, c2 = R1 @ self.centroid + p1[:3], R2 @ self.centroid + p2[:3]
        turn = Rotation.from_matrix(R2 @ R1.T).as_rotvec()
        R = Rotation.from_rotvec(turn * steps).as_matrix() @ R2
        c = c2 + (c2 - c1) * steps
        return np.array([*(c - R @ self.centroid), *angles_from_matrix(R)])
