"""Tasks the GUI runs in its worker thread: one match, a batch over frames, automatic placement.

Each builder takes plain inputs gathered on the GUI thread (numpy arrays, Views, prepared
meshes, file paths) and returns ``task(reporter)`` for ``worker.TaskRunner``. Nothing here
touches Qt objects; the payloads are plain dataclasses.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from fluorogui.core.geometry import View
from fluorogui.core.initialise import assign_blobs, dark_blobs
from fluorogui.core.matching import MatchProblem, MatchResult, MatchSettings, match
from fluorogui.core.mesh import PreparedMesh
from fluorogui.core.pipeline import predicted_outline, segment_outlines
from fluorogui.core.spline import OutlineSpline
from fluorogui.io.images import read_image

OVERLAY_SPACING_PX = 3.0
#: a batch stops (tracking lost) when a frame's mean outline distance exceeds this (mm)
LOST_TRACK_MM = 1.5
#: automatic outlines are re-segmented until a pass moves the pose less than this (mm, deg)
SETTLED = 0.02
MAX_PASSES = 8


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
class MatchOutcome:
    """A finished match of one component in one frame, with the outlines it used."""

    component: str
    frame: int
    result: MatchResult
    outlines_px: list[np.ndarray] | None  # auto-segmented outlines (None: the given ones were used)


@dataclass
class BatchProgress:
    done: int
    total: int
    frame: int
    seconds: float


@dataclass
class BatchOutcome:
    component: str
    frames_done: list[int]
    stopped_at: int | None = None
    reason: str = ""


def _segment_and_match(images, views, mesh, start, settings, splines, passes, progress, cancel):
    """Match from ``start``. Without ``splines``, segment the outlines along the pose and
    match, again and again (at least twice, at most ``passes`` times) until a pass moves
    the pose by less than ``SETTLED``: a start several mm / degrees off leaves parts of the
    true edge outside the first segmentation band, and each pass brings more of it in."""
    pose = np.asarray(start, dtype=float)
    outlines = None
    calls, seconds, result = 0, 0.0, None
    for k in range(max(1, passes) if splines is None else 1):
        if splines is None or k > 0:
            outlines = segment_outlines(images, views, mesh, pose)
            splines = [OutlineSpline.fit(o) for o in outlines]
        result = match(MatchProblem(mesh, views, splines), pose, settings, progress, cancel)
        calls += result.calls
        seconds += result.seconds
        moved = np.abs(result.pose - pose)
        pose = result.pose
        if result.cancelled or (k >= 1 and moved.max() < SETTLED):
            break
    result.calls, result.seconds = calls, seconds
    return result, outlines


def match_task(component: str, frame: int, images: Sequence[np.ndarray], views: Sequence[View],
               mesh: PreparedMesh, start, settings: MatchSettings, splines: list[OutlineSpline] | None,
               passes: int = MAX_PASSES):
    """One component in one frame; live updates carry the model outline for the overlays."""

    def task(reporter) -> MatchOutcome:
        history: list[float] = []

        def progress(calls, objective, pose):
            history.append(float(objective))
            if reporter.due():
                outlines = [predicted_outline(mesh, pose, view, OVERLAY_SPACING_PX) for view in views]
                reporter.report(LiveUpdate(component, int(calls), float(objective), np.array(pose), outlines,
                                           list(history)))

        result, outlines = _segment_and_match(images, views, mesh, start, settings, splines, passes,
                                              progress, reporter.cancelled)
        result.history = history or result.history  # every pass, not just the last
        return MatchOutcome(component, frame, result, outlines)

    return task


def batch_task(component: str, frames: Sequence[int], image_paths: Sequence[Sequence[Path]],
               views: Sequence[View], mesh: PreparedMesh, start, settings: MatchSettings,
               reviewed_outlines: dict[int, list[np.ndarray]]):
    """Track a component through ``frames`` (image_paths[k] = the frame's file per view), each
    starting from the previous result. Reviewed outlines are used as they are; other frames
    are segmented automatically. Every frame's MatchOutcome is emitted as an item."""

    def task(reporter) -> BatchOutcome:
        pose = np.asarray(start, dtype=float)
        done: list[int] = []
        t0 = time.perf_counter()
        for k, (frame, paths) in enumerate(zip(frames, image_paths)):
            reporter.check()
            images = [read_image(p) for p in paths]
            given = reviewed_outlines.get(frame)
            splines = [OutlineSpline.fit(o) for o in given] if given else None
            try:
                result, outlines = _segment_and_match(images, views, mesh, pose, settings, splines, MAX_PASSES, None,
                                                      reporter.cancelled)
            except ValueError as exc:  # no usable edges along the predicted outline
                return BatchOutcome(component, done, frame, f"frame {frame}: {exc}")
            if result.cancelled:
                break
            reporter.emit(MatchOutcome(component, frame, result, outlines))
            done.append(frame)
            reporter.report(BatchProgress(k + 1, len(frames), frame, time.perf_counter() - t0), force=True)
            worst = max(result.per_view_mean_mm) if result.per_view_mean_mm else np.inf
            if not result.converged or worst > LOST_TRACK_MM:
                why = "did not converge" if not result.converged else f"outline distance {worst:.2f} mm"
                return BatchOutcome(component, done, frame, f"frame {frame}: {why}; check its outlines")
            pose = result.pose
        return BatchOutcome(component, done)

    return task


@dataclass
class PlacementOutcome:
    poses: dict[str, np.ndarray]
    iou: dict[str, float]


def placement_task(images: Sequence[np.ndarray], views: Sequence[View], meshes: dict[str, PreparedMesh]):
    """Find every component automatically: dark blobs, which blob is which, pose search."""

    def task(reporter) -> PlacementOutcome:
        reporter.report("Finding implants in the images…", force=True)
        blobs = [dark_blobs(image) for image in images]
        if not all(blobs):
            raise ValueError("no implant-like dark region found in one of the views")
        found = assign_blobs(meshes, views, blobs, progress=lambda text: reporter.report(text, force=True),
                             cancel=reporter.cancelled)
        reporter.check()
        return PlacementOutcome({n: a.result.pose for n, a in found.items()},
                                {n: a.result.mean_iou for n, a in found.items()})

    return task
