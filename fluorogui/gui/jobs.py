"""The workflow's jobs as tasks of the GUI's worker thread.

A job (``Session.match_job`` / ``find_job`` / ``track_job``) is plain data taken from the
session on the GUI thread; it runs anywhere and never touches the session. Each builder
here wraps one into ``task(reporter)`` for ``worker.TaskRunner``: the job's progress
becomes throttled ``reporter.report`` payloads, tracked frames become ``reporter.emit``
items (every one arrives, in order), and the cancel flag is the reporter's. The GUI
thread stores what comes back with ``Session.store`` / ``store_placements``. There is
no matching loop of the GUI's own: the app, the command line and scripts run the same
code on the same frame and get the same pose.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from fluorogui.core.matching.loop import predicted_outline
from fluorogui.core.search.find import Placement
from fluorogui.core.status import Status
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.tracking import by_frame

OVERLAY_SPACING_PX = 3.0


@dataclass
class LiveUpdate:
    """A match in progress: call count, objective, pose and the model outline per view."""

    component: str
    calls: int
    objective_mm: float
    pose: np.ndarray
    outlines_px: list[np.ndarray]
    history: list[float] = field(default_factory=list)


@dataclass
class FindProgress:
    fraction: float
    text: str


@dataclass
class TrackedFrame:
    """The results of one tracked frame (one per component), with the run's progress."""

    frame: int
    results: list[FrameResult]
    done: int
    total: int
    elapsed_s: float
    next_frame: int | None = None

    @property
    def eta_s(self) -> float:
        """Time left at the average time per frame so far."""
        return self.elapsed_s / self.done * (self.total - self.done) if self.done else float("nan")


@dataclass
class TrackOutcome:
    done: int
    total: int
    elapsed_s: float


def frame_status(results) -> str:
    """The worst status among a frame's new results: failed, needs review or matched
    (kept results were accepted or already matched)."""
    statuses = {r.status for r in results if not r.kept}
    for status in (Status.FAILED, Status.NEEDS_REVIEW):
        if status in statuses:
            return status
    return Status.MATCHED


def match_task(job):
    """Match the components of ``job`` (a ``MatchJob``); live updates carry the model
    outline for the overlays, throttled by the runner."""
    meshes = {i.component: i.mesh for i in job.inputs}

    def task(reporter) -> list[FrameResult]:
        histories = {name: [] for name in meshes}

        def live(component, calls, objective_mm, pose):
            histories[component].append(float(objective_mm))
            if not reporter.due():
                return
            try:
                outlines = [predicted_outline(meshes[component], pose, view, OVERLAY_SPACING_PX)
                            for view in job.views]
            except ValueError:  # e.g. a start behind the source: nothing to draw yet
                return
            reporter.report(LiveUpdate(component, int(calls), float(objective_mm), np.array(pose, dtype=float),
                                       outlines, list(histories[component])))

        results = job.run(live, reporter.cancelled)
        reporter.check()
        return results

    return task


def find_task(job):
    """Find the components of ``job`` (a ``FindJob``) with progress (fraction, text)."""

    def task(reporter) -> dict[str, Placement]:
        reporter.report(FindProgress(0.0, "Looking for the implants…"), force=True)

        def progress(fraction, text):
            reporter.report(FindProgress(float(fraction), str(text)))

        placements = job.run(progress, reporter.cancelled)
        reporter.check()
        return placements

    return task


def track_task(job):
    """Track ``job`` (a ``TrackJob``) frame by frame: every frame's results arrive as a
    ``TrackedFrame`` item; a cancel stops after the frame in progress (not stored)."""

    def task(reporter) -> TrackOutcome:
        total = len(job.frames)
        t0 = time.perf_counter()
        done = 0
        for results in by_frame(job.run(None, reporter.cancelled), len(job.components)):
            done += 1
            following = job.frames[done] if done < total else None
            reporter.emit(TrackedFrame(results[0].frame, results, done, total, time.perf_counter() - t0, following))
        reporter.check()
        return TrackOutcome(done, total, time.perf_counter() - t0)

    return task
