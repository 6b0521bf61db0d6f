"""From images to a pose without hand-made outlines: the one segment -> match -> re-segment loop.

The outline of a component is segmented along the projection of a rough pose
(``edges.component_outline``). When that pose is several degrees off, parts of the true
edge fall outside the search band and the spline bridges them with a chord; matching
and segmenting again along the matched pose removes that, as a user reviewing the
outline would. The loop runs at least ``LoopSettings.min_passes`` passes (one when the
first pass moved less than ``settled_first``, or when its model outline, the shift in the
image set aside, lies within ``settled_first_px`` of the start's: the first segmentation
searches for that shift, so its outline was already chosen along the right pose) and
stops when
a pass moves the model centroid by less than ``LoopSettings.settled`` mm and turns it by
less than that many degrees, or after ``max_passes``. (Re-segmentation jitters the pose
by a few hundredths of a mm / degree on real images, so a tighter threshold would only
spend passes.) Given outlines (reviewed by the user) are matched once, as they are.

Where part of the outline is too faint for Canny's default thresholds (a tibial keel in
bone next to the tray and the femoral component), component_outline searches the
uncovered runs again with lower thresholds instead of bridging them. Where another
component overlaps this one (``occluded`` masks), its edges are left out of the
segmentation and the matcher ignores the outline there.

Everything that matches a component from images - the desktop app, the command line,
tracking and scripts - goes through ``segment_and_match``, so the same frame and the
same settings give the same pose everywhere.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, replace
from typing import Sequence

import numpy as np

from fluorogui.core.cancel import check_cancel
from fluorogui.core.matching.matcher import judge_match, match
from fluorogui.core.matching.problem import MatchProblem, MatchResult, MatchSettings
from fluorogui.core.matching.quality import QualityThresholds
from fluorogui.core.outlines.edges import component_outline
from fluorogui.core.outlines.rim import RimModel, edge_models, is_soft, refine_outlines
from fluorogui.core.outlines.spline import OutlineError, OutlineSpline
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.projection.pose import motion_between, rotation_matrix
from fluorogui.core.projection.silhouette import mesh_silhouette
from fluorogui.core.threads import each_view


class SegmentationError(ValueError):
    """No usable outline of a component in one view; ``view`` is its 0-based index and
    ``reason`` the problem in plain words."""

    def __init__(self, view: int, reason: str):
        super().__init__(f"view {view + 1}: {reason}")
        self.view = view
        self.reason = reason


@dataclass
class LoopSettings:
    """How automatic outlines are refined: passes and the stopping threshold."""

    min_passes: int = 2
    max_passes: int = 6
    settled: float = 0.05  # a pass moving the centroid less (mm) and turning less (deg) ends the loop
    settled_first: float = 0.25  # ... and the first pass already, when it moved less than this from its start
    # ... or when its model outline, its shift in the image aside, lies within this many pixels of
    # the start's in every view: the edges were chosen along the matched pose already (0: off)
    settled_first_px: float = 1.0
    search_px: int = 60  # first pass: how far the outline may sit from the prediction
    later_search_px: int = 8  # later passes start from a matched pose
    # later passes move the outline to the boundary the metal's rim profile gives (core.rim):
    # "on", "off", or "auto": in the views whose edge is soft (core.rim.is_soft), judged in the
    # second pass (tracking keeps a judgement for the sequence: workflow.framematch.RimJudgement)
    rim: str = "auto"

    def __post_init__(self):
        if isinstance(self.rim, bool):  # the switch of older code: True is "on", False "off"
            self.rim = "on" if self.rim else "off"
        if self.rim not in RIM_MODES:
            raise ValueError(f"rim must be one of {', '.join(RIM_MODES)}, not {self.rim!r}")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict | None) -> "LoopSettings":
        d = d or {}
        known = {k: d[k] for k in cls.__dataclass_fields__ if k in d}
        return cls(**known)  # projects of schema 4 stored rim as true / false: io.project.migrate_4_to_5


RIM_MODES = ("auto", "on", "off")


def outline_change_px(mesh: PreparedMesh, views: Sequence[View], before, after, *, outline_points=None) -> float:
    """How far (pixels, the largest over views) the model outline at ``after`` lies from where
    the same model points are at ``before``, once each view's median shift is taken out: the
    change of shape that a translation of the prediction (which segmentation searches for)
    does not undo. ``outline_points`` (per view, the model points on the outline at ``after``)
    save drawing the silhouettes again."""
    before, after = np.asarray(before, dtype=float), np.asarray(after, dtype=float)
    R0, R1 = rotation_matrix(*before[3:]), rotation_matrix(*after[3:])
    worst = 0.0
    for k, view in enumerate(views):
        if outline_points is not None and k < len(outline_points):
            points = outline_points[k][::4]
        else:
            points = mesh_silhouette(mesh, R1, after[:3], view, spacing_px=4.0).model_points
        change = view.project(points @ R1.T + after[:3]) - view.project(points @ R0.T + before[:3])
        change -= np.median(change, axis=0)
        worst = max(worst, float(np.sqrt((change ** 2).sum(axis=1)).max()))
    return worst


def _outline_points(result: MatchResult) -> list | None:
    """Per view, the model points on the outline at the result's pose, where its evaluation kept them."""
    evaluation = result.evaluation
    return getattr(evaluation[1], "outline_model_points", None) if evaluation is not None else None


def predicted_outline(mesh: PreparedMesh, pose, view: View, spacing_px: float = 2.0) -> np.ndarray:
    """The projected model outline at ``pose`` (pixels), for choosing image edges."""
    pose = np.asarray(pose, dtype=float)
    return mesh_silhouette(mesh, rotation_matrix(*pose[3:]), pose[:3], view).resample(spacing_px=spacing_px).points_px


def segment_outlines(images: Sequence[np.ndarray], views: Sequence[View], mesh: PreparedMesh, pose,
                     *, occluded: Sequence | None = None, search_px: int = 60,
                     only: Sequence[int] | None = None) -> list[np.ndarray | None]:
    """Ordered sub-pixel outline of the component in every image (or only in the views
    ``only``; None for the others), chosen along ``pose``. Raises SegmentationError naming
    the view."""
    def one(k: int) -> np.ndarray | None:
        if only is not None and k not in only:
            return None
        exclude = occluded[k] if occluded is not None and k < len(occluded) else None
        try:
            return component_outline(images[k], predicted_outline(mesh, pose, views[k]), exclude=exclude,
                                     search_px=search_px)
        except ValueError as exc:
            raise SegmentationError(k, str(exc)) from None

    return each_view(one, range(min(len(images), len(views))))  # the views side by side


def refine_rims(images, views, mesh: PreparedMesh, pose, *, outlines: Sequence[np.ndarray | None], occluded=None,
                models: list[RimModel | None] | None = None,
                only: Sequence[int] | None = None) -> tuple[list[np.ndarray | None], list[RimModel | None], list]:
    """Automatic outlines moved to the boundary the metal's rim profile gives at ``pose``
    (``core.outlines.rim``), per view (None stays None; views not in ``only`` stay as they are),
    each image's rim model (fitted unless given in ``models``; the views fitted
    together, one attenuation for the component's metal) and each outline's point
    weights (``core.outlines.profile_fit.precision_weights``; None for the outlines not refined), for
    ``fit_splines``."""
    models = list(models) if models is not None else [None] * len(views)
    refined = list(outlines)
    weights: list = [None] * len(views)
    chosen = [k for k, points in enumerate(outlines) if points is not None and (only is None or k in only)]
    if chosen:
        excludes = [occluded[k] if occluded is not None and k < len(occluded) else None for k in chosen]
        new, fitted, new_weights = refine_outlines([images[k] for k in chosen], [views[k] for k in chosen], mesh,
                                                   pose, outlines_px=[outlines[k] for k in chosen],
                                                   models=[models[k] for k in chosen],
                                                   excludes=excludes)
        for k, outline, model, w in zip(chosen, new, fitted, new_weights):
            refined[k], models[k], weights[k] = outline, model, w
    return refined, models, weights


def soft_edge_views(images, views, mesh: PreparedMesh, pose, *, outlines: Sequence[np.ndarray | None],
                    occluded=None, models: list[RimModel | None] | None = None,
                    cancel=None) -> tuple[list[int], list]:
    """The views (with an outline) whose edge is a soft rim (``core.outlines.rim.is_soft``), judged
    at ``pose`` by each image's rim model: the one in ``models`` or, where that is None,
    judged here, all such views at once (``core.outlines.rim.edge_models``: one attenuation
    for the component's metal, a quick fit where that finds a step, else the full one the
    refinement uses; a view judged alone swung between soft and step from frame to frame
    where its residual curve was flat; over three noise draws the views' own attenuations
    moved a 15 % smaller femur 0.004-0.024 deg further from the truth than the shared one).
    Returns the views and the models. ``cancel`` is checked before the fit (a second or
    more)."""
    models = list(models) if models is not None else [None] * len(views)
    excludes = [occluded[k] if occluded is not None and k < len(occluded) else None for k in range(len(views))]
    judged_here = [k for k, points in enumerate(outlines) if points is not None and models[k] is None]

    if judged_here:
        check_cancel(cancel)
        judged = edge_models([images[k] for k in judged_here], [views[k] for k in judged_here], mesh, pose,
                             outlines_px=[outlines[k] for k in judged_here],
                             excludes=[excludes[k] for k in judged_here])
        for k, model in zip(judged_here, judged):
            models[k] = model
    soft = [k for k, points in enumerate(outlines) if points is not None and is_soft(models[k])]
    return soft, models


def fit_splines(outlines: Sequence[np.ndarray | None], weights: Sequence | None = None) -> list[OutlineSpline | None]:
    """Splines through outlines (None stays None), with their points' ``weights`` where
    given (per view, None: all alike); raises SegmentationError naming the view."""
    splines = []
    for k, points in enumerate(outlines):
        if points is None:
            splines.append(None)
            continue
        try:
            splines.append(OutlineSpline.fit(points, weights=weights[k] if weights is not None else None))
        except (OutlineError, ValueError) as exc:
            raise SegmentationError(k, str(exc)) from None
    return splines


def splines_from_images(images, views, mesh, pose, *, occluded=None, search_px: int = 60) -> list[OutlineSpline]:
    return fit_splines(segment_outlines(images, views, mesh, pose, occluded=occluded, search_px=search_px))


def segment_and_match(images, views, mesh: PreparedMesh, start, *, settings: MatchSettings | None = None,
                      loop: LoopSettings | None = None, splines: Sequence[OutlineSpline | None] | None = None,
                      occluded: Sequence | None = None, progress=None, cancel=None,
                      rim_models: list[RimModel | None] | None = None,
                      thresholds: QualityThresholds | None = None) -> MatchResult:
    """Match one component in one frame from ``start`` (mm, degrees), segmenting its outlines.

    The one segment -> match -> re-segment loop of the app, the command line, tracking and
    scripts.

    Parameters
    ----------
    images : sequence of numpy.ndarray
        One image per view, float in [0, 1].
    views : sequence of View
    mesh : PreparedMesh
    start : array_like of 6 float
        The start pose, mm and degrees.
    settings : MatchSettings, optional
        The matcher's settings (default: the fast method).
    loop : LoopSettings, optional
        Passes, when the loop has settled, search bands and the rim refinement.
    splines : sequence of OutlineSpline or None, optional
        Reviewed outlines per view (None where a view has none): used as they are.
    occluded : sequence of numpy.ndarray or None, optional
        Per view, a boolean mask of where another component hides this one.
    progress, cancel : callable, optional
        As for :func:`~fluorogui.core.matching.matcher.match`.
    rim_models : list, optional
        Per view, the rim model fitted in an earlier frame of the sequence (None entries
        are filled in here, for the next frame).
    thresholds : QualityThresholds, optional
        The limits the result is judged by (``judge_match``): the project's; the defaults
        when omitted.

    Returns
    -------
    MatchResult
        As :func:`~fluorogui.core.matching.matcher.match` returns, plus ``splines`` (the
        outlines it was matched on), ``image_outlines`` (the automatic ones), their
        ``outline_weights`` and ``passes``.

    Raises
    ------
    SegmentationError
        No outline could be traced in the first pass.
    fluorogui.core.cancel.Cancelled
        ``cancel()`` turned true.

    Notes
    -----
    ``splines`` are given (reviewed) outlines, per view, None where a view has none. With
    a given outline in every view: one match on them. Otherwise the missing views are
    segmented along the pose and matched, again and again (at least ``loop.min_passes``,
    at most ``loop.max_passes`` passes) until a pass moves the model by less than
    ``loop.settled``. A segmentation failure in the first pass raises SegmentationError;
    in a later pass the previous pass's result stands. The result carries the splines it
    was matched on (``MatchResult.splines``), the automatic outlines among them
    (``image_outlines``: None for given views, and None overall when all were given), their
    points' weights and the number of passes.

    With ``loop.rim`` "on" the passes after the first move the automatic outlines to the
    boundary the metal's rim profile gives (``core.outlines.rim``); with "auto" (the default) only
    in the views whose edge the second pass finds soft (``soft_edge_views``: a thin rim
    darkening inside the silhouette, where Canny's outline lies inside it and the pose
    would be biased; real images have shown step edges, which stay as Canny puts them).
    Fitting an image's rim model (attenuation and blur) is most of that work and they are
    the same for a whole sequence: ``rim_models`` (a list, one entry per view) gives them,
    and its None entries are filled in with the ones fitted here, for the next frame. The
    first refining pass also matches the plain outlines and the refined ones are kept only
    when they fit the model better (a lower objective); otherwise the loop goes on without
    them. ``result.settings["rim_refined"]`` says per view whether the result's outline
    was refined.

    Examples
    --------
    The demo's femoral component from a start 2-3 mm / degrees off:

    >>> import numpy as np
    >>> from fluorogui import Session
    >>> from fluorogui.core.matching.loop import LoopSettings
    >>> from fluorogui.simulation.demo import demo_project_path
    >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
    >>> truth = np.array(session.project.settings["demo_truth"]["0"]["femoral"])
    >>> result = segment_and_match(session.images(0), session.views, session.mesh("femoral"),
    ...                            truth + [2, -2, 1, 3, -2, 2], loop=LoopSettings(rim="off"))
    >>> result.converged, result.passes >= 2
    (True, True)
    >>> bool(np.abs(result.pose - truth).max() < 0.5)
    True
    """
    settings = settings or MatchSettings()
    loop = loop or LoopSettings()
    pose = np.asarray(start, dtype=float)
    given = list(splines) if splines is not None else [None] * len(views)
    missing = [k for k, g in enumerate(given) if g is None]
    outlines, outline_weights = None, None
    current = given
    total_calls, total_seconds, history = 0, 0.0, []
    result, passes = None, 0
    if rim_models is None:
        rim_models = [None] * len(views)
    # the views whose outlines the rim refinement moves; None until judged ("auto")
    rim_views = {"on": missing, "off": []}.get(loop.rim)
    if rim_views is None and all(rim_models[k] is not None for k in missing):  # judged in an earlier frame
        rim_views = [k for k in missing if is_soft(rim_models[k])]
    use_rim, refined = loop.rim != "off", False
    for k in range(max(1, loop.max_passes) if missing else 1):
        trial = None  # the first rim pass: the plain outlines, to compare with
        check_cancel(cancel)
        if missing:
            try:
                new_outlines = segment_outlines(images, views, mesh, pose, occluded=occluded,
                                                search_px=loop.search_px if k == 0 else loop.later_search_px,
                                                only=missing)
                weights = None  # the refined outlines' point weights, per view
                if use_rim and k > 0:  # the pose is a matched one: its rim profiles are the image's
                    if rim_views is None:
                        rim_views, judged = soft_edge_views(images, views, mesh, pose, outlines=new_outlines,
                                                            occluded=occluded,
                                                            models=rim_models, cancel=cancel)
                        rim_models[:] = judged
                    if rim_views and not refined:
                        trial = (new_outlines, fit_splines(new_outlines))
                    if rim_views:
                        check_cancel(cancel)
                        new_outlines, fitted, weights = refine_rims(images, views, mesh, pose, outlines=new_outlines,
                                                                    occluded=occluded, models=rim_models,
                                                                    only=rim_views)
                        rim_models[:] = fitted
                        refined = True
                new_splines = fit_splines(new_outlines, weights)
            except SegmentationError:
                if result is None:
                    raise
                break  # keep the previous pass
            outlines, outline_weights = new_outlines, weights
            current = [g if g is not None else n for g, n in zip(given, new_splines)]
        # later passes start from a matched pose: no need to centre the model first
        pass_settings = settings if passes == 0 or not settings.centre_first else replace(settings, centre_first=False)
        previous = pose
        # each pass's result is judged (checks, uncertainty) only once the loop has kept it
        problem = MatchProblem(mesh, views, current, occluded)
        result = match(problem, pose, pass_settings, progress=progress, cancel=cancel, judge=False)
        if trial is not None:
            # keep the rim's outlines only where they fit the model better than Canny's own:
            # on an image the rim model does not describe, they would only add noise
            plain = [g if g is not None else n for g, n in zip(given, trial[1])]
            plain_problem = MatchProblem(mesh, views, plain, occluded)
            other = match(plain_problem, pose, pass_settings, progress=progress, cancel=cancel, judge=False)
            total_calls += other.calls
            total_seconds += other.seconds
            if other.objective_mm <= result.objective_mm:
                result, outlines, current, use_rim = other, trial[0], plain, False
                outline_weights, problem = None, plain_problem
        passes += 1
        total_calls += result.calls
        total_seconds += result.seconds
        history += result.history
        moved = max(motion_between(result.pose, previous, mesh.centroid))
        pose = result.pose
        # a later pass is still owed: to judge the edge ("auto") or to refine it for the first time
        rim_pending = bool(missing) and use_rim and (rim_views is None or (bool(rim_views) and not refined))
        if passes >= loop.min_passes and moved < loop.settled and not rim_pending:
            break
        if passes == 1 and not rim_pending and (
                moved < loop.settled_first
                or outline_change_px(mesh, views, previous, pose,
                                     outline_points=_outline_points(result)) < loop.settled_first_px):
            # the start was within a fraction of a pixel: segmenting along the result would
            # pick the same edges (the search band is several pixels wide)
            break
    t_judge = time.perf_counter()
    result = judge_match(problem, result, pass_settings, thresholds)
    total_seconds += time.perf_counter() - t_judge
    return replace(result, calls=total_calls, seconds=total_seconds, history=history,
                   settings=dict(result.settings, loop=loop.to_dict(), passes=passes,
                                 rim_refined=[k in (rim_views or []) and refined and use_rim
                                              for k in range(len(views))]),
                   splines=list(current), image_outlines=outlines, outline_weights=outline_weights, passes=passes)


def match_images(images, views, mesh: PreparedMesh, start, *, settings: MatchSettings | None = None,
                 passes: int | None = None, progress=None, cancel=None,
                 occluded=None) -> tuple[MatchResult, list[OutlineSpline]]:
    """``segment_and_match`` on automatic outlines, returning (result, splines); ``passes``
    caps the passes (and, if below the default minimum, lowers it)."""
    loop = LoopSettings()
    if passes is not None:
        loop.max_passes = max(1, int(passes))
        loop.min_passes = min(loop.min_passes, loop.max_passes)
    out = segment_and_match(images, views, mesh, start, settings=settings, loop=loop, splines=None,
                            occluded=occluded, progress=progress, cancel=cancel)
    return out, out.splines
