"""The paper's method (Eq. 4-6): an even point cloud of the model, the grid outline of its
projection (Fig. 4), N equally spaced outline points, the mean distance to the image
spline per view summed over views (Eq. 5), BFGS on the six pose variables with
finite-difference gradients, stopping when every variable changes by < 0.0005 or after
800 objective calls (then flagged non-convergent).
"""
from __future__ import annotations

import numpy as np
from scipy import optimize

from fluorogui.core.cancel import check_cancel
from fluorogui.core.matching.problem import MatchProblem, MatchResult, MatchSettings, _to_state
from fluorogui.core.outlines.spline import resample_closed_polyline
from fluorogui.core.projection.point_outline import grid_outline, point_spacing_px
from fluorogui.core.projection.pose import rotation_matrix


class _CallLimit(Exception):
    pass


# -- the paper's objective ----------------------------------------------------------------------


def paper_view_distances(problem: MatchProblem, pose: np.ndarray, settings: MatchSettings) -> list[np.ndarray]:
    """Eq. (4) distances (mm on the intensifier) of the paper's outline points, per view."""
    cloud = problem.cloud(settings.model_points, settings.seed)
    R = rotation_matrix(*pose[3:])
    X = cloud @ R.T + pose[:3]
    out = []
    for view, spline in zip(problem.views, problem.splines):
        uv = view.project(X)
        depth = float((R @ problem.mesh.centroid + pose[:3] - view.source) @ view.normal)
        px_per_mm = view.focal_px[0] / depth
        cell = 2.0 * point_spacing_px(len(cloud), problem.mesh.area, px_per_mm)
        outline = grid_outline(uv, cell)
        if settings.outline_spacing_mm:
            pts = resample_closed_polyline(outline, spacing=settings.outline_spacing_mm / view.mm_per_px())
        else:
            pts = resample_closed_polyline(outline, n=settings.outline_points or 60)
        d = spline.closest_secant(pts)[0] if hasattr(spline, "closest_secant") else spline.closest(pts)[0]
        out.append(np.asarray(d) * view.mm_per_px())
    return out


def match_paper(problem, start, settings, progress, *, cancel) -> MatchResult:
    centroid = problem.mesh.centroid
    _, c0 = _to_state(start, centroid)
    x0 = np.array([*c0, *start[3:]])
    calls = [0]
    best = [np.inf, x0.copy(), None]
    history: list[float] = []

    def pose_of(x):
        R = rotation_matrix(*x[3:])
        return np.array([*(x[:3] - R @ centroid), *x[3:]])

    def f(x):
        check_cancel(cancel)
        if calls[0] >= settings.max_calls:
            raise _CallLimit
        calls[0] += 1
        d = paper_view_distances(problem, pose_of(x), settings)
        value = float(sum(v.mean() for v in d))
        history.append(value)
        if value < best[0]:
            best[:] = [value, x.copy(), [float(v.mean()) for v in d]]
        if progress is not None:
            progress(calls[0], value, pose_of(x))
        return value

    previous = [x0.copy()]
    converged = [False]

    def callback(xk):
        if np.all(np.abs(xk - previous[0]) < settings.xtol):
            converged[0] = True
            raise StopIteration
        previous[0] = xk.copy()

    message = ""
    try:
        # jac=None: forward differences with the absolute step `eps` (mm, degrees)
        out = optimize.minimize(f, x0, method="BFGS", jac=None, callback=callback,
                                options={"eps": settings.fd_step, "gtol": 0.0, "maxiter": 10_000})
        message = "" if converged[0] else f"BFGS stopped: {out.message}"
    except _CallLimit:
        message = "call limit reached"
    _, x_best, per_view = best
    if per_view is None:
        per_view = [float(v.mean()) for v in paper_view_distances(problem, pose_of(x_best), settings)]
    return MatchResult(pose=pose_of(x_best), objective_mm=float(sum(per_view)), per_view_mean_mm=per_view,
                       calls=calls[0], seconds=0.0, converged=converged[0], method="paper",
                       settings=settings.to_dict(), message="" if converged[0] else message, history=history)
