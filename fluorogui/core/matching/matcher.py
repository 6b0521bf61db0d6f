"""Pose of one component from its outlines in two views (paper Eq. 4–6 and a fast variant):
``match`` runs a method from one or more starts and judges the result. The methods are
``paper`` (``matching.paper``) and ``fast`` (``matching.fast``); the settings, problem
and result are in ``matching.problem``, the uncertainty in ``matching.uncertainty``.

Every result is then judged on its own evidence (``core.matching.quality.check_match``) and gets
its uncertainty (``pose_covariance``, six SDs in ``MatchResult.sd``): ``converged`` means
the optimiser stopped and the checks passed; otherwise ``message`` says what failed.

Poses in and out follow the DESIGN.md convention (mm, degrees). The objective is in mm
on the intensifier plane (pixels times pixel pitch), as in the paper.
"""
from __future__ import annotations

import time
from dataclasses import replace
from typing import Callable

import numpy as np

from fluorogui.core.matching.fast import match_fast
from fluorogui.core.matching.paper import match_paper
from fluorogui.core.matching.problem import MatchProblem, MatchResult, MatchSettings, ProgressCallback
from fluorogui.core.matching.quality import QualityThresholds, match_checks
from fluorogui.core.matching.uncertainty import covariances, pose_sd
from fluorogui.core.projection.pose import as_pose


def match(problem: MatchProblem, start, settings: MatchSettings | None = None, *,
          progress: ProgressCallback | None = None, cancel: Callable[[], bool] | None = None,
          judge: bool = True, thresholds: QualityThresholds | None = None) -> MatchResult:
    """The pose of one component from its outlines in one or two views (Eq. 4-6).

    Runs the method ``settings.method`` from ``start`` (and ``settings.starts - 1``
    perturbed starts; the best is kept), then judges the result on its own evidence
    (:func:`~fluorogui.core.matching.quality.check_match`) and computes its uncertainty.

    Parameters
    ----------
    problem : MatchProblem
        The mesh, the views and one image outline spline per view (and optional
        occlusion masks).
    start : array_like of 6 float
        The start pose, mm and degrees.
    settings : MatchSettings, optional
        Defaults to ``MatchSettings()`` (the fast method).
    progress : callable, optional
        ``progress(calls, objective_mm, pose)`` after every step.
    cancel : callable, optional
        Polled; when it returns True the match stops.
    judge : bool, optional
        False leaves out the checks and the uncertainty (``judge_match`` adds them later),
        for a caller that may discard the result, e.g. a pass the loop will redo.
    thresholds : QualityThresholds, optional
        The limits the checks apply (the project's); the defaults when omitted.

    Returns
    -------
    MatchResult
        ``pose``, ``objective_mm`` (sum over views of the mean outline distance, mm on the
        intensifier), ``per_view_mean_mm``, ``calls``, ``seconds``, ``sd`` (six SDs) and
        ``converged``: the optimiser stopped *and* the checks passed (else ``message``
        says what failed).

    Raises
    ------
    ValueError
        An unknown method or settings no match can use (e.g. fewer than 8 outline points).
    fluorogui.core.cancel.Cancelled
        ``cancel()`` turned true.

    See Also
    --------
    fluorogui.core.matching.loop.segment_and_match : From images, with automatic outlines.

    Examples
    --------
    Match the demo's femoral component on its outlines traced at the true pose:

    >>> import numpy as np
    >>> from fluorogui import Session
    >>> from fluorogui.core.matching.loop import splines_from_images
    >>> from fluorogui.core.matching.problem import MatchProblem
    >>> from fluorogui.simulation.demo import demo_project_path
    >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
    >>> truth = np.array(session.project.settings["demo_truth"]["0"]["femoral"])
    >>> mesh = session.mesh("femoral")
    >>> splines = splines_from_images(session.images(0), session.views, mesh, truth)
    >>> result = match(MatchProblem(mesh, session.views, splines), truth + [2, -1, 1, 3, -2, 2])
    >>> result.converged, bool(np.abs(result.pose - truth).max() < 0.5)
    (True, True)
    """
    settings = settings or MatchSettings()
    start = as_pose(start)
    if settings.method not in ("fast", "paper"):
        raise ValueError(f"unknown method {settings.method!r} (use 'fast' or 'paper')")
    settings.validate()
    runner = match_fast if settings.method == "fast" else match_paper
    t0 = time.perf_counter()
    rng = np.random.default_rng(settings.seed)
    best: MatchResult | None = None
    total_calls = 0
    for k in range(max(1, settings.starts)):
        s = start.copy()
        if k > 0:
            s[:3] += rng.normal(0, settings.restart_sd[0], 3)
            s[3:] += rng.normal(0, settings.restart_sd[1], 3)
        res = runner(problem, s, settings, progress=progress, cancel=cancel)
        total_calls += res.calls
        if best is None or res.objective_mm < best.objective_mm:
            best = res
    best = replace(best, calls=total_calls, optimiser_converged=best.converged)
    if judge:
        best = judge_match(problem, best, settings, thresholds)
    return replace(best, seconds=time.perf_counter() - t0)


def judge_match(problem: MatchProblem, result: MatchResult, settings: MatchSettings | None = None,
                thresholds: QualityThresholds | None = None) -> MatchResult:
    """The verdict: ``result`` judged, as a copy with its uncertainty and its own evidence
    (``core.matching.quality.match_checks``, against ``thresholds``: the project's or the
    command line's, the defaults when None). A result that fails a check comes back not
    converged, saying why in ``message`` and naming the checks in ``failed``; ``result``
    itself is never changed (a ``MatchResult`` is frozen)."""
    settings = settings or MatchSettings()
    try:
        pose_cov, body_cov = covariances(problem, result.pose, settings=settings, evaluation=result.evaluation)
        judged = replace(result, sd=pose_sd(pose_cov), sd_body=pose_sd(body_cov),
                         cov_body=body_cov if np.all(np.isfinite(body_cov)) else None)
    except ValueError:  # the model behind a source at this pose
        judged = replace(result, sd=[float("inf")] * 6, sd_body=[float("inf")] * 6)
    problems = match_checks(problem, judged, thresholds)
    judged = replace(judged, failed=[name for name, _ in problems])
    if problems:
        judged = replace(judged, converged=False, message="; ".join(
            ([result.message] if result.message else []) + [text for _, text in problems]))
    return judged
