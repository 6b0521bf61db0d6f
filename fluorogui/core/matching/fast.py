"""The fast method.

``method="fast"`` keeps the objective family (distances from projected model outline
points to the image splines) but: the outline is the exact mesh silhouette, each outline
point carries the model point it images, so the residuals have analytic derivatives with
correspondences frozen within an evaluation; residuals are signed point-to-curve
distances in both directions (model to image, and image to model, which stops the
outline from sliding onto part of the image outline) with a Huber loss against occluded
or mis-segmented outline parts, each view's residuals weighted alike or, where the
outline carries point weights (``OutlineSpline.weight_at``: the rim refinement's
precision), by them; the pose is parametrised about the model centroid with
rotations scaled by the model radius, so rotation and translation steps are equally
conditioned; Levenberg–Marquardt steps; an initial translation from the outline
centroids in both views; optional restarts.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from fluorogui.core.cancel import check_cancel
from fluorogui.core.matching.problem import (
    MIN_VISIBLE_POINTS,
    MatchProblem,
    MatchResult,
    MatchSettings,
    _to_pose,
    _to_state,
    visible_points,
)
from fluorogui.core.projection.pose import rotvec_matrix
from fluorogui.core.projection.silhouette import mesh_silhouette
from fluorogui.core.threads import each_view

# -- the fast method ----------------------------------------------------------------------------

#: a step (under 100 x xtol) whose quadratic model promises less than this share of the
#: robust cost ends a match before it is evaluated: the cost changes by about 1e-3 of itself
#: from pose to pose on real outlines (the outline point set changes), so such a step cannot
#: be told from noise. Retried with more damping (which barely changes a step while the
#: damping is small) it cost 3-8 evaluations per tibial match on consecutive real frames;
#: evaluated once to see it rejected (or taken, and the next one judged) it cost one or two
#: of the 4.3 a consecutive real match made (see ``_below_noise``)
NOISE_FLOOR = 1e-3


def _times_skew(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rows a_i^T [v_i]x (N, 3), i.e. a_i x v_i, written out (no (N, 3, 3) matrices)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * v[:, 2] - a[:, 2] * v[:, 1]
    out[:, 1] = a[:, 2] * v[:, 0] - a[:, 0] * v[:, 2]
    out[:, 2] = a[:, 0] * v[:, 1] - a[:, 1] * v[:, 0]
    return out


def _polyline_normals(points: np.ndarray, at: np.ndarray | None = None) -> np.ndarray:
    """Unit normals of a closed polyline from its central differences (at the indices ``at``)."""
    at = np.arange(len(points)) if at is None else np.asarray(at)
    t = points[(at + 1) % len(points)] - points[at - 1]
    n = np.column_stack([t[:, 1], -t[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


class _FastEvaluation:
    """Residuals and Jacobian of the fast objective at one pose (correspondences frozen)."""

    def __init__(self, problem: MatchProblem, R, c, settings: MatchSettings, image_samples, image_params=None):
        mesh = problem.mesh
        t = c - R @ mesh.centroid
        rho = mesh.radius
        self.per_view_mm: list[float] = []
        self.outlines_px: list[np.ndarray] = []
        self.outline_model_points: list[np.ndarray] = []  # per view, the model points imaged on the outline
        self.r, self.J, self.w = [], [], []
        # per residual block: its view and where along the image outline (px of chord
        # length) each residual sits, for the covariance's clusters of neighbours
        self.view_of: list[int] = []
        self.where: list[np.ndarray | None] = []

        def one(k: int) -> tuple:  # a view's measures, on its own (the views run side by side)
            return _view_residuals(problem, k, R, t, settings=settings, g=image_samples[k],
                                   image_params=None if image_params is None else image_params[k])

        views = range(min(len(problem.views), len(problem.splines), len(image_samples)))
        for k, (mm, sil, blocks) in enumerate(each_view(one, views)):
            self.per_view_mm.append(mm)
            self.outlines_px.append(sil.points_px)
            self.outline_model_points.append(sil.model_points)
            for r, nJ, X, weights, where in blocks:
                self._add(r, nJ, X, c, rho=rho, weights=weights)
                self.view_of.append(k)
                self.where.append(where)
        self.objective_mm = float(sum(self.per_view_mm))

    def _add(self, r: np.ndarray, nJ: np.ndarray, X: np.ndarray, c: np.ndarray, *, rho: float,
             weights: np.ndarray | None = None) -> None:
        """Residual rows with d/d(delta_c [mm], omega*rho [mm]) for X' = exp(w)(X - c) + c + delta;
        each block (one view, one direction) sums to weight 1, shared by the outline's
        ``weight_at`` where it has weights."""
        J = np.empty((len(r), 6))  # [nJ | -(nJ x (X - c)) / rho], written in place (no hstack)
        J[:, :3] = nJ
        skew = _times_skew(nJ, X - c)
        np.divide(np.negative(skew, out=skew), rho, out=J[:, 3:])
        self.r.append(r)
        self.J.append(J)
        self.w.append(np.full(len(r), 1.0 / len(r)) if weights is None else weights / np.sum(weights))

    def robust_cost(self, huber: float) -> float:
        total = 0.0
        for r, w in zip(self.r, self.w):
            a = np.abs(r)
            rho = np.where(a <= huber, 0.5 * a * a, huber * (a - 0.5 * huber))
            total += float(np.sum(w * rho))
        return total

    def normal_equations(self, huber: float):
        H = np.zeros((6, 6))
        g = np.zeros(6)
        for r, J, w in zip(self.r, self.J, self.w):
            a = np.abs(r)
            irls = np.where(a <= huber, 1.0, huber / np.maximum(a, 1e-12))
            ww = w * irls
            H += J.T @ (J * ww[:, None])
            g += J.T @ (ww * r)
        return H, g


def _view_residuals(problem: MatchProblem, k: int, R, t, *, settings: MatchSettings, g, image_params) -> tuple:
    """One view's part of ``_FastEvaluation``: its mean outline distance (mm), its silhouette
    and its residual blocks (signed distances, their Jacobian along the normal, the model
    points, weights, where along the image outline)."""
    view, spline, mask = problem.views[k], problem.splines[k], problem.occluder(k)
    if settings.outline_points:
        sil = mesh_silhouette(problem.mesh, R, t, view, spacing_px=1.0)
        fwd = sil.resample(n=settings.outline_points)
    else:
        sil = fwd = mesh_silhouette(problem.mesh, R, t, view, spacing_px=settings.model_spacing_px)
    # model outline points to the image spline: signed distance along the spline normal
    X = fwd.model_points @ R.T + t
    uv, Jp = view.project_jacobian(X)
    if mask is not None:
        seen = visible_points(mask, uv)
        X, uv, Jp = X[seen], uv[seen], Jp[seen]
    dist, closest_pt, normal, t_near = spline.closest(uv)
    if settings.skip_gaps and len(spline.gaps):
        # a model point whose nearest image outline is a chord across missing or
        # hidden edges has nothing to be measured against
        on_edge = ~spline.in_gap(t_near)
        if on_edge.sum() >= MIN_VISIBLE_POINTS:
            X, uv, Jp = X[on_edge], uv[on_edge], Jp[on_edge]
            dist, closest_pt, normal = dist[on_edge], closest_pt[on_edge], normal[on_edge]
            t_near = t_near[on_edge]
    blocks = [(np.einsum("ij,ij->i", normal, uv - closest_pt), np.einsum("ij,ijk->ik", normal, Jp), X,
               spline.weight_at(t_near), t_near)]
    if settings.symmetric:
        # image outline samples to the model outline (the dense silhouette polyline)
        _, idx = cKDTree(sil.points_px).query(g)
        n_model = _polyline_normals(sil.points_px, idx)
        Xm = sil.model_points[idx] @ R.T + t
        uvm, Jm = view.project_jacobian(Xm)
        blocks.append((np.einsum("ij,ij->i", n_model, uvm - g), np.einsum("ij,ijk->ik", n_model, Jm), Xm,
                       None if image_params is None else spline.weight_at(image_params), image_params))
    return float(np.mean(dist)) * view.mm_per_px(), sil, blocks


def _below_noise(move: np.ndarray, promised: float, cost: float, xtol: float) -> bool:
    """Is a step (``move``: each variable's change, mm and degrees) too small to tell from the
    objective's noise: every variable under ``xtol``, or under 100 x ``xtol`` with a promised
    gain below ``NOISE_FLOOR`` of the cost? Judged before the step is evaluated: evaluating
    it (a silhouette and the closest points per view) only showed it taken by a hair or
    rejected. On frames 51-69 of the real sequence that halved the evaluations (216 -> 105),
    moving the poses by at most 0.024 mm / 0.13 deg (the tray about its stem, whose SD is
    larger); on the generated 100-frame bend the RMS error against the truth stayed 0.0023 mm /
    0.0047 deg (femur) and 0.0029 mm / 0.0086 deg (tray)."""
    return bool(np.all(move < xtol) or (np.all(move < 100 * xtol) and promised < NOISE_FLOOR * cost))


def _initial_translation(problem: MatchProblem, R, c, image_samples, *, iterations: int = 3) -> np.ndarray:
    """Shift the centroid so the silhouette centroids meet the image-outline centroids."""
    mesh = problem.mesh
    for _ in range(iterations):
        A, b = [], []
        for view, g in zip(problem.views, image_samples):
            # a centroid: a coarse silhouette is enough
            sil = mesh_silhouette(mesh, R, c - R @ mesh.centroid, view, scale=1.0, spacing_px=2.0)
            shift = _polygon_centroid(g) - _polygon_centroid(sil.points_px)
            _, Jc = view.project_jacobian(c[None, :])
            A.append(Jc[0])
            b.append(shift)
        delta = np.linalg.lstsq(np.vstack(A), np.concatenate(b), rcond=None)[0]
        c = c + delta
        if np.linalg.norm(delta) < 0.5:  # the optimiser does the rest
            break
    return c


def _polygon_centroid(p: np.ndarray) -> np.ndarray:
    x, y = p[:, 0], p[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    cross = x * y1 - x1 * y
    a = cross.sum() / 2.0
    if abs(a) < 1e-9:
        return p.mean(0)
    return np.array([((x + x1) * cross).sum(), ((y + y1) * cross).sum()]) / (6.0 * a)


def _image_samples(problem: MatchProblem, settings: MatchSettings, whole: bool = False) -> list[np.ndarray]:
    """Image outline samples per view (about ``spacing_px`` apart, or ``outline_points``);
    unless ``whole``, without chords across gaps and without occluded points."""
    if whole:
        return [s.sample(n) for s, n in zip(problem.splines, _sample_counts(problem, settings))]
    return _samples_and_params(problem, settings)[0]


def _sample_counts(problem: MatchProblem, settings: MatchSettings) -> list[int]:
    return [settings.outline_points or max(16, int(s.length_px / settings.spacing_px)) for s in problem.splines]


def _samples_and_params(problem: MatchProblem, settings: MatchSettings):
    """``_image_samples`` (not ``whole``) and, per view, where each sample sits along its
    outline (its spline parameter: the covariance's stretches, the point weights)."""
    params = [s.sample_params(n, skip_gaps=settings.skip_gaps and len(s.gaps) > 0)
              for s, n in zip(problem.splines, _sample_counts(problem, settings))]
    samples, kept = [], []
    for k, (s, t) in enumerate(zip(problem.splines, params)):
        g = s.evaluate(t)
        seen = visible_points(problem.occluder(k), g)
        samples.append(g[seen])
        kept.append(t[seen])
    return samples, kept


def match_fast(problem, start, settings, progress, *, cancel) -> MatchResult:
    mesh = problem.mesh
    R, c = _to_state(start, mesh.centroid)
    if settings.centre_first:  # whole outlines: centroids of closed curves
        c = _initial_translation(problem, R, c, _image_samples(problem, settings, whole=True))
    # the samples, and where each sits along its outline (for the covariance's stretches)
    image_samples, image_params = _samples_and_params(problem, settings)
    calls = 0
    history: list[float] = []
    lam = 1e-3
    huber = settings.huber_px
    ev = _FastEvaluation(problem, R, c, settings, image_samples, image_params)
    calls += 1
    cost = ev.robust_cost(huber)
    history.append(ev.objective_mm)
    converged = False
    while calls < settings.max_calls:
        check_cancel(cancel)
        H, g = ev.normal_equations(huber)
        step = np.linalg.solve(H + lam * np.diag(np.diag(H) + 1e-9), -g)
        dc, w = step[:3], step[3:] / mesh.radius
        # the change of the variables we move: centroid (mm) and rotation (deg)
        move = np.r_[np.abs(dc), np.degrees(np.abs(w))]
        if _below_noise(move, -(g @ step + 0.5 * step @ H @ step), cost, settings.xtol):
            converged = True
            break
        R_new = rotvec_matrix(w) @ R
        c_new = c + dc
        try:
            ev_new = _FastEvaluation(problem, R_new, c_new, settings, image_samples, image_params)
        except ValueError:
            ev_new = None
        calls += 1
        new_cost = ev_new.robust_cost(huber) if ev_new is not None else np.inf
        if new_cost <= cost:
            pose_new = _to_pose(R_new, c_new, mesh.centroid)
            R, c, ev, cost = R_new, c_new, ev_new, new_cost
            lam = max(lam / 3.0, 1e-7)
            history.append(ev.objective_mm)
            if progress is not None:
                progress(calls, ev.objective_mm, pose_new)
        else:
            # a rejected step this small is the objective's noise floor (the outline point set
            # changes from pose to pose): more damping would only spend evaluations
            if np.all(move < 10 * settings.xtol):
                converged = True
                break
            lam *= 10.0
            if lam > 1e8:
                converged = bool(np.all(np.abs(step) < 10 * settings.xtol))
                break
    pose = _to_pose(R, c, mesh.centroid)
    return MatchResult(pose=pose, objective_mm=ev.objective_mm, per_view_mean_mm=ev.per_view_mm, calls=calls,
                       seconds=0.0, converged=converged, method="fast", settings=settings.to_dict(),
                       message="" if converged else "did not converge", history=history,
                       normal_matrix=ev.normal_equations(huber)[0], outlines_px=ev.outlines_px,
                       evaluation=(pose, ev))
