"""Matching the components of one frame, with quality checks and recovery.

This is the step tracking repeats and the app's *Match* (and ``fluorogui match``) runs:
for each component, the one segment -> match loop (``core.matching.loop.segment_and_match``)
from a start pose, with the other components' current projections masked out where they
overlap (``occlusion_masks``) and so is whatever lies beyond the intensifier's field of
view (``_hidden``: a component partly out of view is matched on what is visible), then
every quality check (``core.matching.quality``). A frame that fails a
check is not given up at once: other starts are tried - the last matched pose when the
prediction extrapolated, a search near the prediction (*find implants*; first, before the
prediction itself, when the last match is several frames back, and then near where the
images located the component: ``ComponentInput.located``), the prediction
turned by a few degrees about the recent motion axis (between neighbouring frames), and
a search of the whole image - and the best result is kept (recovery starts run a
shorter loop). Whatever fails its checks in the end is returned as
``needs_review``; a frame where no outline could be traced at all is ``failed``. The jump
allowed from the prediction grows with the number of frames since the last match.

Everything here reads only what it is given (images, views, meshes, outlines), so it
runs in a worker thread or another process without touching the session.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from fluorogui.core.cancel import OutOfTime, check_cancel, with_deadline
from fluorogui.core.matching.loop import SegmentationError, segment_and_match
from fluorogui.core.matching.problem import MatchProblem
from fluorogui.core.matching.quality import (
    assess,
    failed_checks,
    hidden_where_no_edges,
    weak_view,
    weak_view_problem,
)
from fluorogui.core.matching.uncertainty import covariances, pose_sd
from fluorogui.core.outlines.field import field_of_view
from fluorogui.core.outlines.rim import MAYBE_SOFT_BELOW_MU
from fluorogui.core.outlines.spline import OutlineSpline
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.projection.pose import angles_from_matrix, motion_between, rotation_matrix
from fluorogui.core.projection.silhouette import projected_region
from fluorogui.core.status import Status
from fluorogui.core.threads import each_view, single_threaded_blas
from fluorogui.workflow import messages
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.settings import WorkflowSettings

_RANK = {Status.MATCHED: 0, Status.NEEDS_REVIEW: 1, Status.FAILED: 2}

#: frames since the last match beyond which recovery searches near the prediction first
NEAR_FIRST_GAP = 2
#: checks whose failure no other start can mend, once every other check passed: the component
#: is partly beyond the field of view (``quality._partly_visible``), so its pose is loose or too
#: little of it is seen from any start; or the outlines leave the fitted pose more uncertain than
#: the project allows (``uncertainty``: the SDs belong to the outlines, not to the start). Recovery
#: stops there (frame 260's femur of the real sequence tried 6 starts for 1.7-2.2 s, each flagged
#: the same)
IMAGE_BOUND_CHECKS = frozenset({"visible", "uncertainty"})

#: a component's rim judgement (``core.outlines.rim``: per view, is the edge a soft rim, and its
#: attenuation and blur) is the same for a whole sequence; unless its first matched frame
#: finds a clear step it rests on this many matched frames, each judged on its own, not on
#: the first attempt alone (which may land at a wrong pose, and 4 of 106 real views fitted
#: soft where their neighbours fit steps)
RIM_JUDGE_FRAMES = 3


@dataclass
class ComponentInput:
    """What matching one component in one frame needs besides the images."""

    component: str
    mesh: PreparedMesh
    start: np.ndarray  # the predicted pose
    fallback: np.ndarray | None = None  # the last matched pose, when the prediction extrapolated
    given: list[OutlineSpline | None] | None = None  # reviewed outlines per view (None: segment)
    typical_view_mm: float | None = None
    axis: np.ndarray | None = None  # unit axis (world) of the recent rotation, for turned starts
    gap: int = 1  # frame numbers since the last matched frame: the jump allowed grows with it
    probe: bool = True  # look for a second orientation that fits as well (no motion to tell them apart)
    predicted: bool = True  # ``start`` predicts the pose (tracking): far from it is suspect; a hand placement is not
    search: bool = True  # recovery may search with *find implants* (off where that was tried already)
    first: np.ndarray | None = None  # a start tried before ``start``: this frame's own earlier match
    located: np.ndarray | None = None  # at a jump: ``start`` moved to where the images put the component; searched near


def occlusion_masks(views: Sequence[View], others: Sequence[tuple[PreparedMesh, np.ndarray]], near: np.ndarray | None,
                    mesh: PreparedMesh | None, *, margin_px: int = 3) -> list[np.ndarray | None] | None:
    """Per view, where the other components (mesh, pose) project, grown by ``margin_px``;
    None for a view where they do not come near this component's projection at ``near``
    (and None overall when no view needs a mask)."""
    placed = [(other_mesh, rotation_matrix(*np.asarray(pose, dtype=float)[3:]), np.asarray(pose, dtype=float)[:3])
              for other_mesh, pose in others]

    def one(view: View) -> np.ndarray | None:
        mask = projected_region(view, placed, margin_px)
        if not mask.any():
            return None
        if near is not None and mesh is not None:
            lo, hi = _projected_box(mesh, near, view)
            box = mask[max(lo[1] - 20, 0):max(hi[1] + 20, 0), max(lo[0] - 20, 0):max(hi[0] + 20, 0)]
            if not box.any():
                return None
        return mask

    out = each_view(one, views)  # the views side by side
    return out if any(m is not None for m in out) else None


def _projected_box(mesh: PreparedMesh, pose, view: View) -> tuple[np.ndarray, np.ndarray]:
    """Pixel box (lo, hi) holding the projection of the mesh's bounding box at ``pose``."""
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    pose = np.asarray(pose, dtype=float)
    uv = view.project(corners @ rotation_matrix(*pose[3:]).T + pose[:3])
    return np.floor(uv.min(0)).astype(int), np.ceil(uv.max(0)).astype(int)


def turned(pose: np.ndarray, centroid: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """``pose`` turned by ``degrees`` about a world ``axis`` through the model centroid."""
    R = rotation_matrix(*pose[3:])
    c = R @ centroid + pose[:3]
    R2 = Rotation.from_rotvec(np.radians(degrees) * np.asarray(axis, float)).as_matrix() @ R
    return np.array([*(c - R2 @ centroid), *angles_from_matrix(R2)])


class FrameMatcher:
    """Matches components in frames of one session set-up (views, settings, find)."""

    def __init__(self, views: Sequence[View], settings: WorkflowSettings | None = None,
                 find_near: Callable | None = None, *, live: Callable | None = None,
                 rim: dict[str, list] | None = None) -> None:
        single_threaded_blas()  # (core.threads: BLAS's own threads only spin beside the views')
        self.views = list(views)
        self.settings = settings or WorkflowSettings()
        # find_near(images, component, mesh, pose or None (the whole image), cancel) -> pose, poses or None
        self.find_near = find_near
        self.live = live  # live(component, calls, objective_mm, pose) at every step of a match
        # each component's rim models per view (core.outlines.rim): judged in its first matched frames, then
        # reused; ``rim`` (component -> models per view) are ones judged before (kept in the project)
        self.rim_judgements: dict[str, RimJudgement] = {
            c: RimJudgement.settled_with(models) for c, models in (rim or {}).items()
            if len(models) == len(self.views) and all(m is not None for m in models)}
        self._frame: tuple[list, dict] | None = None  # see _frame_state

    def _frame_state(self, images) -> dict:
        """What is worked out once per frame, for this set of images: "fields" (their
        fields of view), "rims" (component -> a matched attempt's rim models) and "searches"
        ((component, centre) -> a search's placement). Holding the images keeps their ids
        unique while they are compared by identity."""
        held = self._frame
        if held is None or len(held[0]) != len(images) or any(a is not b for a, b in zip(held[0], images)):
            held = self._frame = (list(images), {"rims": {}})
        return held[1]

    def _fields(self, images) -> list[np.ndarray]:
        """The fields of view of this frame's images (computed once per set of images)."""
        state = self._frame_state(images)
        if "fields" not in state:
            state["fields"] = each_view(lambda image: field_of_view(image, margin_px=2), images)  # side by side
        return state["fields"]

    def _hidden(self, images, occluded) -> list[np.ndarray]:
        """Per view, what a component cannot be seen through: the other components (``occluded``,
        per view or None) and whatever lies beyond the intensifier's field of view (and the
        image). Segmentation, the match and its checks use only the rest: a component partly
        out of view is matched on what is visible (judged by ``quality.judge`` on that too)."""
        out = []
        for k, field in enumerate(self._fields(images)):
            other = occluded[k] if occluded is not None and k < len(occluded) else None
            out.append(~field if other is None else (other | ~field))
        return out

    def _rims_for(self, images, component: str) -> list:
        """The rim models an attempt starts with: those of a matched attempt in this frame
        (an image's rim does not change with the start, and judging it again in every probe
        cost a second or more per view), else the component's judgement so far."""
        matched = self._frame_state(images)["rims"]
        if component in matched:
            return list(matched[component])
        return self.rim_judgements.setdefault(component, RimJudgement(len(self.views))).for_attempt()

    # -- one attempt ---------------------------------------------------------------------------
    def attempt(self, images, job: ComponentInput, start, occluded, *, cancel, loop=None) -> FrameResult:
        """One segment -> match loop from ``start`` and the quality checks of its result."""
        s = self.settings
        t0 = time.perf_counter()
        loop = loop or s.loop
        step = None
        if self.live is not None:
            def step(calls, objective, pose, _c=job.component):
                self.live(_c, calls, objective, pose)
        hidden = self._hidden(images, occluded)
        try:
            rims = self._rims_for(images, job.component)
            out = segment_and_match(images, self.views, job.mesh, start, settings=s.match, loop=loop,
                                    splines=job.given, occluded=hidden,
                                    progress=step, cancel=cancel, rim_models=rims, thresholds=s.quality)
        except SegmentationError as exc:
            return FrameResult(0, job.component, None, Status.FAILED, messages.segmentation_failed(job.component, exc),
                               seconds=time.perf_counter() - t0, failed=["segmentation"])
        except ValueError as exc:  # e.g. the model behind the source at this start
            return FrameResult(0, job.component, None, Status.FAILED, messages.match_failed(job.component, exc),
                               seconds=time.perf_counter() - t0, failed=["match"])
        result = out
        outlines = [sp.sample(max(64, int(sp.length_px)), skip_gaps=True) for sp in out.splines]
        quality = assess(images, self.views, job.mesh, result.pose, converged=result.converged,
                         per_view_mean_mm=result.per_view_mean_mm,
                         image_outlines=outlines, predicted=job.start if job.predicted else None, occluded=hidden,
                         tol_px=s.quality.tol_px,
                         fields=self._fields(images), model_outlines=result.outlines_px, sd=result.sd,
                         sd_body=result.sd_body)
        limits = replace(s.quality, max_jump_mm=s.quality.max_jump_mm * max(1, job.gap),
                         max_jump_deg=s.quality.max_jump_deg * max(1, job.gap))
        problems = failed_checks(quality, thresholds=limits, typical_view_mm=job.typical_view_mm,
                                 view_names=[f"view {k + 1}" for k in range(len(images))],
                                 why_not_converged=result.message)
        weak = weak_view(problems, quality, s.quality)
        if weak is not None:  # one view's edges are weak, nothing else fails: judged by the others
            problems = self._judged_without(weak, job, out, hidden, images=images, quality=quality)
        status = Status.NEEDS_REVIEW if problems else Status.MATCHED
        reason = "; ".join(text for _, text in problems)
        failed = [name for name, _ in problems]
        if "converged" in failed and result.optimiser_converged and result.failed:
            failed = [*result.failed, *(name for name in failed if name != "converged")]  # which of its own checks
        if status == Status.MATCHED:
            self._frame_state(images)["rims"][job.component] = list(rims)
        return FrameResult(0, job.component, result.pose, status, reason, result, quality, out.image_outlines,
                           time.perf_counter() - t0, rim_models=rims, outline_weights=out.outline_weights,
                           failed=failed)

    def _judged_without(self, weak: int, job: ComponentInput, out, hidden, *, images, quality) -> list[tuple[str, str]]:
        """A pose whose view ``weak`` has weak edges, judged by the other views' outlines and
        the stretches of the weak view's outline that lie on image edges (the rest hidden,
        ``quality.weak_view_problem``): passed when they pin it down, else flagged (as
        ``edge_support``) naming the direction they leave loose."""
        masks = list(hidden)
        masks[weak] = hidden_where_no_edges(images[weak], out.outlines_px[weak], hidden[weak],
                                       tol_px=self.settings.quality.tol_px)
        problem = MatchProblem(job.mesh, self.views, out.splines, masks)
        try:
            _, body = covariances(problem, out.pose, settings=self.settings.match)
        except ValueError:
            body = np.full((6, 6), np.inf)
        text = weak_view_problem(weak, self.views, body[:3, :3], pose_sd(body), edge=quality.edge_support[weak],
                                 thresholds=self.settings.quality)
        return [("edge_support", text)] if text else []

    # -- one component, with recovery ------------------------------------------------------------
    def match_component(self, frame: int, images, job: ComponentInput, occluded=None, *,
                        cancel: Callable[[], bool] | None = None) -> FrameResult:
        """The best of the attempts from the prediction and, while none passes its checks,
        from the recovery starts; ``frame`` is only recorded in the result."""
        t0 = time.perf_counter()
        best: FrameResult | None = None
        tried = 0
        light = replace(self.settings.loop, max_passes=min(3, self.settings.loop.max_passes))
        jump = job.gap > NEAR_FIRST_GAP
        limit = self.settings.tracking.max_seconds
        # recovery (its searches and every start after the first) stops at the time limit,
        # raising OutOfTime; the first start and the probe run to their end
        bounded = with_deadline(cancel, t0 + limit if limit > 0 else None)
        try:
            for label, start in self._starts(images, job, bounded):
                check_cancel(bounded if tried else cancel)
                # only the first start runs the whole loop: recovery starts (every later one, and
                # every start at a jump, where the prediction extrapolates beyond what was seen)
                # get a shorter one, most lead nowhere
                whole = tried == 0 and not label and not jump
                tried += 1  # (a start stopped at the time limit was tried too)
                candidate = self.attempt(images, job, start, occluded, cancel=bounded if tried > 1 else cancel,
                                         loop=None if whole else light)
                if best is None or better_result(candidate, best):
                    best = candidate
                    best.recovered = label
                if best.status == Status.MATCHED:
                    break
                if best.failed and set(best.failed) <= IMAGE_BOUND_CHECKS:
                    break  # the pose fits; what fails is what the images show, the same from every start
                if job.given is not None and all(g is not None for g in job.given) and best.status == Status.FAILED:
                    break  # reviewed outlines that cannot be matched: other starts will not help
        except OutOfTime:
            best = _out_of_time(job, best, time.perf_counter() - t0, limit)
        if best.status == Status.MATCHED and job.probe and self.settings.tracking.probe:
            best, tried = self._probe(images, job, best, occluded, cancel=cancel, tried=tried)
        if best.status == Status.MATCHED:  # one vote per frame, from its best result only
            judgement = self.rim_judgements[job.component]
            judgement.add(best.rim_models)
            if judgement.is_settled:
                best.rim_settled = list(judgement.settled)  # for the project to keep
        best.frame, best.attempts, best.seconds = frame, tried, time.perf_counter() - t0
        if best.pose is None:
            best.pose = np.asarray(job.start, dtype=float).copy()  # the prediction, as a start for the user
        return best

    def _probe(self, images, job: ComponentInput, best: FrameResult, occluded, *, cancel, tried: int):
        """Is there a second orientation that fits as well? Starts turned by ``probe_deg``
        either way about the axis the outlines constrain least (a tibial tray about its
        stem, a symmetric part about its axis): a better fit replaces ``best``; a distinct
        one within ``probe_ratio`` of its objective makes the result ambiguous."""
        t = self.settings.tracking
        light = replace(self.settings.loop, max_passes=min(3, self.settings.loop.max_passes))
        axis = best.match.weakest_rotation_axis() if best.match is not None else None
        if axis is None:
            return best, tried
        start_pose = best.pose
        for sign in (1.0, -1.0):
            start = turned(start_pose, job.mesh.centroid, axis, sign * t.probe_deg)
            other = self.attempt(images, job, start, occluded, cancel=cancel, loop=light)
            tried += 1
            if other.status != Status.MATCHED:
                continue
            turn = motion_between(other.pose, best.pose, job.mesh.centroid)[1]
            if turn < 2.0:
                continue  # the same pose again
            if other.match.objective_mm < best.match.objective_mm:
                best, other = other, best  # the probe found the better fit
                best.recovered = "probe"
            if other.match.objective_mm <= t.probe_ratio * best.match.objective_mm:
                best.status = Status.NEEDS_REVIEW
                best.failed = [*best.failed, "ambiguous"]
                best.reason = (f"ambiguous: another orientation {turn:.0f}° away fits almost as well "
                               f"(outline distance {other.match.objective_mm:.2f} vs "
                               f"{best.match.objective_mm:.2f} mm) — check which is right")
                break
        return best, tried

    def _starts(self, images, job: ComponentInput, cancel):
        """(label, start) pairs, cheapest and likeliest first; each is computed only when
        the ones before it failed. Where the last match is more than ``NEAR_FIRST_GAP`` frames
        back, the prediction extrapolates the motion further than it was seen, and the
        searches come first (near the prediction, then the whole image): on the real
        sequence's 10-20 frame jumps, full loops from the prediction and from the last pose
        failed in most such frames and cost 1-4 s, where a search and a match from its
        placement took well under one. When the images located the component
        (``ComponentInput.located``) and the search there placed it, the whole image is not
        searched: it would show the same place."""
        t = self.settings.tracking
        search = self._may_search(job)
        searches_first = self._searches_first(job)
        if job.first is not None:
            yield "", np.asarray(job.first, dtype=float)
        if searches_first:
            placed = yield from self._search(images, job, cancel, near=True)
            if not (placed and job.located is not None):  # (else the whole image shows the same place)
                yield from self._search(images, job, cancel, near=False)
        yield "", np.asarray(job.start, dtype=float)
        if not t.recover:
            return
        if job.fallback is not None and np.abs(np.asarray(job.fallback) - job.start).max() > 0.5:
            yield "last pose", np.asarray(job.fallback, dtype=float)
        if search and not searches_first:
            yield from self._search(images, job, cancel, near=True)
        if job.gap <= 2:
            yield from self._turned_starts(job)
        if search and not searches_first:
            yield from self._search(images, job, cancel, near=False)

    def _may_search(self, job: ComponentInput) -> bool:
        t = self.settings.tracking
        return bool(t.recover and t.find_near and self.find_near is not None and job.search)

    def _searches_first(self, job: ComponentInput) -> bool:
        """After a jump the searches come before the prediction (``_starts``)."""
        return self._may_search(job) and job.gap > NEAR_FIRST_GAP

    def _mask_placement(self, images, job: ComponentInput, cancel) -> tuple[np.ndarray, float]:
        """Where the other components' masks put ``job``'s component until it is matched, and
        the seconds that took: its prediction or, after a jump (the searches come first,
        the prediction extrapolates beyond the motion seen), the first placement of the
        search near it, made here rather than in its own match (once per frame either way).
        Masked at the extrapolation, the femur was matched again in every jump of the real
        sequence once the tibia landed more than 1 mm from it."""
        start = np.asarray(job.start, float)
        if not self._searches_first(job) or job.first is not None:
            return start, 0.0
        t0 = time.perf_counter()
        placed = next(iter(self._search(images, job, cancel, near=True)), None)
        return (start if placed is None else placed[1]), time.perf_counter() - t0

    def _search(self, images, job: ComponentInput, cancel, near: bool):
        """*Find implants* near the prediction (where the images located the component, at a
        jump), or in the whole image: its placements, if any (returns whether there were).
        A search sees no masks, so one already made in this frame (a second round) is not
        made again."""
        centre = None
        if near:
            centre = np.asarray(job.located if job.located is not None else job.start, float)
        made = self._frame_state(images).setdefault("searches", {})
        key = (job.component, None if centre is None else centre.tobytes())
        if key not in made:
            made[key] = self.find_near(images, job.component, job.mesh, centre, cancel)
        placed = made[key]  # a pose, poses best first, or None
        poses = [] if placed is None or len(placed) == 0 else np.atleast_2d(np.asarray(placed, dtype=float))
        for pose in poses:
            yield ("find near the prediction" if near else "find implants"), pose
        return len(poses) > 0

    def _turned_starts(self, job: ComponentInput):
        """A small miss between neighbouring frames: the prediction turned a little either
        way about the recent motion axis (or the model's own axes)."""
        t = self.settings.tracking
        centroid = job.mesh.centroid
        if job.axis is not None and np.linalg.norm(job.axis) > 0:
            axes = [np.asarray(job.axis, float) / np.linalg.norm(job.axis)]
        else:
            R = rotation_matrix(*job.start[3:])
            axes = [R[:, k] for k in range(3)]  # the model's own axes in the world
        for axis in axes:
            for sign in (1.0, -1.0):
                yield "turned start", turned(job.start, centroid, axis, sign * t.rotated_start_deg)

    # -- all components of a frame ----------------------------------------------------------------
    def match_frame(self, frame: int, images, jobs: Sequence[ComponentInput], *, fixed: dict | None = None,
                    cancel: Callable[[], bool] | None = None) -> dict[str, FrameResult]:
        """Match ``jobs`` in order, each with the others masked at their best known pose
        in this frame (``fixed``: component -> (mesh, pose) of components not matched here,
        e.g. accepted ones; one not matched yet: its prediction or, after a jump, where the
        search near it places it, ``_mask_placement``). When a component matched later moved
        far from the pose the earlier ones were masked with, those are matched again."""
        known = dict(fixed or {})
        searched: dict[str, float] = {}  # seconds of a search made for the masks, counted as the component's
        for job in jobs:
            placed = np.asarray(job.start, float)
            if len(jobs) > 1 and job.component not in known:
                placed, searched[job.component] = self._mask_placement(images, job, cancel)
            known.setdefault(job.component, (job.mesh, placed))
        results: dict[str, FrameResult] = {}
        masked_with: dict[str, dict[str, np.ndarray]] = {}
        for job in jobs:
            results[job.component] = self._match_masked(frame, images, job, known, masked_with=masked_with,
                                                        cancel=cancel)
            results[job.component].seconds += searched.get(job.component, 0.0)
            if results[job.component].pose is not None and results[job.component].status != Status.FAILED:
                known[job.component] = (job.mesh, results[job.component].pose)
        if self.settings.tracking.occlusion and len(jobs) > 1:
            for job in jobs:  # a second round where a mask was placed far from where the other ended up
                used = masked_with.get(job.component, {})
                if any(_moved(known[o][0], used[o], known[o][1]) for o in used):
                    # from its own match with the old mask, if it had one: the best start there is
                    earlier = results[job.component]
                    again = replace(job, first=earlier.pose) if earlier.status == Status.MATCHED else job
                    results[job.component] = self._match_masked(frame, images, again, known, masked_with=masked_with,
                                                                cancel=cancel)
                    # the component's time and attempts in this frame: both rounds
                    results[job.component].seconds += earlier.seconds
                    results[job.component].attempts += earlier.attempts
                    if results[job.component].status != Status.FAILED:
                        known[job.component] = (job.mesh, results[job.component].pose)
        return results

    def _match_masked(self, frame, images, job, known, *, masked_with, cancel) -> FrameResult:
        t = self.settings.tracking
        occluded = None
        if t.occlusion:
            others = [(m, p) for name, (m, p) in known.items() if name != job.component]
            occluded = occlusion_masks(self.views, others, job.start, job.mesh, margin_px=t.occlusion_margin_px)
            masked_with[job.component] = {name: p.copy() for name, (m, p) in known.items()
                                          if name != job.component} if occluded is not None else {}
        return self.match_component(frame, images, job, occluded, cancel=cancel)


class RimJudgement:
    """One component's rim models per view through a sequence, judged in its matched
    frames. A view whose first matched frame finds a clear step (an attenuation of
    ``core.outlines.rim.MAYBE_SOFT_BELOW_MU`` or more: not refined, and most real views) keeps that;
    any other view is judged again in each matched frame until ``RIM_JUDGE_FRAMES`` have,
    then keeps the model of median attenuation among theirs. ``for_attempt`` hands each
    attempt the settled views' models and None where its own frame is to judge (the list
    ``core.matching.loop.segment_and_match`` fills)."""

    def __init__(self, n_views: int) -> None:
        self.votes: list[list] = [[] for _ in range(n_views)]
        self.settled: list = [None] * n_views

    @classmethod
    def settled_with(cls, models: list) -> "RimJudgement":
        """A judgement made before (e.g. in an earlier run on the same images)."""
        judgement = cls(len(models))
        judgement.settled = list(models)
        return judgement

    @property
    def is_settled(self) -> bool:
        return all(m is not None for m in self.settled)

    def for_attempt(self) -> list:
        return self.settled if all(m is not None for m in self.settled) else list(self.settled)

    def add(self, models: list | None) -> None:
        """A matched frame's models (None entries: views it did not judge)."""
        for k, model in enumerate(models or []):
            if model is None or self.settled[k] is not None:
                continue
            self.votes[k].append(model)
            clear_step = len(self.votes[k]) == 1 and model.mu >= MAYBE_SOFT_BELOW_MU
            if clear_step or len(self.votes[k]) >= RIM_JUDGE_FRAMES:
                self.settled[k] = sorted(self.votes[k], key=lambda m: m.mu)[len(self.votes[k]) // 2]


def _out_of_time(job: ComponentInput, best: FrameResult | None, seconds: float, limit: float) -> FrameResult:
    """The best result when recovery ran out of time (``TrackingSettings.max_seconds``): none
    matched (recovery ends at the first that does), so it stays flagged, its reason saying so."""
    note = messages.out_of_time(seconds, limit)
    if best is None:  # a search before the first start took the time
        return FrameResult(0, job.component, None, Status.FAILED, note, seconds=seconds, failed=["time"])
    best.reason = f"{note}; {best.reason}" if best.reason else note
    best.failed = [*best.failed, "time"]
    return best


def better_result(a: FrameResult, b: FrameResult) -> bool:
    """Is ``a`` a better result than ``b``: a better status, then a lower objective."""
    if _RANK[a.status] != _RANK[b.status]:
        return _RANK[a.status] < _RANK[b.status]
    oa = a.match.objective_mm if a.match is not None else np.inf
    ob = b.match.objective_mm if b.match is not None else np.inf
    return oa < ob


def _moved(mesh: PreparedMesh, before: np.ndarray, after: np.ndarray, limit_mm: float = 1.0) -> bool:
    """Did a mask's component end up more than ``limit_mm`` from where it was masked?"""
    travel, turn = motion_between(before, after, mesh.centroid)
    return travel > limit_mm or turn * np.pi / 180 * mesh.radius > limit_mm
