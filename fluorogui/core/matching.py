"""Pose of one component from its outlines in two views (paper Eq. 4–6 and a fast variant).

``method="paper"`` reproduces the paper: an even point cloud of the model, the grid
outline of its projection (Fig. 4), N equally spaced outline points, the mean distance to
the image spline per view summed over views (Eq. 5), BFGS on the six pose variables with
finite-difference gradients, stopping when every variable changes by < 0.0005 or after
800 objective calls (then flagged non-convergent).

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

Every result is then judged on its own evidence (``core.quality.check_match``) and gets
its uncertainty (``pose_covariance``, six SDs in ``MatchResult.sd``): ``converged`` means
the optimiser stopped and the checks passed; otherwise ``message`` says what failed.

Poses in and out follow the DESIGN.md convention (mm, degrees). The objective is in mm
on the intensifier plane (pixels times pixel pitch), as in the paper.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from typing import Callable, Sequence

import numpy as np
from scipy import optimize
from scipy.spatial import cKDTree

from .geometry import View
from .mesh import PreparedMesh, sample_surface
from .outline import grid_outline, point_spacing_px
from .pose import angles_from_matrix, as_pose, pose_difference, rotation_matrix, rotvec_matrix
from .silhouette import mesh_silhouette
from .spline import resample_closed_polyline

ProgressCallback = Callable[[int, float, np.ndarray], None]


class MatchCancelled(Exception):
    """Raised inside the optimiser when the caller's cancel flag is set."""


class _CallLimit(Exception):
    pass


@dataclass
class MatchSettings:
    method: str = "fast"  # "fast" or "paper"
    outline_points: int | None = None  # paper: N equally spaced (default 60); fast: None = one per `spacing_px`
    outline_spacing_mm: float | None = None  # paper alternative: one point every d mm on the intensifier
    model_points: int = 15000  # paper: size of the point cloud
    max_calls: int = 800
    xtol: float = 0.0005  # mm and degrees: stop when every variable changes less
    fd_step: float = 0.1  # paper: finite-difference step (mm, deg); the paper does not give one
    spacing_px: float = 2.0  # fast: spacing of image outline points when outline_points is None
    # fast: spacing of model outline points (outline_points None); 2 px apart, the points kept
    # shift enough from pose to pose to make the cost ripple (tests/core/test_cost_smoothness.py)
    model_spacing_px: float = 1.0
    huber_px: float = 2.0  # fast: Huber threshold of the robust loss
    symmetric: bool = True  # fast: add image-to-model residuals
    skip_gaps: bool = True  # fast: no residuals on chords the outline draws across gaps
    centre_first: bool = True  # fast: first shift the model so the outline centroids meet
    starts: int = 1  # independent starts (the given one plus perturbed ones); the best is kept
    restart_sd: tuple[float, float] = (5.0, 5.0)  # mm, deg for the extra starts
    seed: int = 0

    def to_dict(self) -> dict:
        return asdict(self)

    def validate(self) -> None:
        """Refuse settings the matcher cannot work with (ValueError naming the option)."""
        if self.outline_points is not None and self.outline_points < MIN_OUTLINE_POINTS:
            raise ValueError(f"--outline-points {self.outline_points}: at least {MIN_OUTLINE_POINTS} outline "
                             "points per view are needed to fix six pose variables")
        if self.model_points < 100:
            raise ValueError(f"--points {self.model_points}: a point model needs at least 100 points")
        if self.starts < 1 or self.max_calls < 1:
            raise ValueError("starts and max_calls must be positive")


#: fewest outline points per view a match accepts (six unknowns, with room for noise)
MIN_OUTLINE_POINTS = 8


@dataclass
class MatchResult:
    pose: np.ndarray
    objective_mm: float
    per_view_mean_mm: list[float]
    calls: int
    seconds: float
    converged: bool
    method: str
    settings: dict
    cancelled: bool = False
    message: str = ""
    history: list[float] = field(default_factory=list)
    #: fast method: the 6x6 Gauss-Newton matrix at the result, in the matcher's variables
    #: (centroid shift mm, rotation vector x model radius mm); says how well each direction
    #: of motion is pinned down by the outlines
    normal_matrix: np.ndarray | None = field(default=None, repr=False)
    #: fast method: the model outline (pixels) per view at the result, about 1 px apart
    outlines_px: list | None = field(default=None, repr=False)
    #: standard deviations of the six pose variables (mm, deg) from the Gauss-Newton
    #: covariance at the result (``pose_covariance``); inf where the outlines fix nothing
    sd: list[float] | None = None
    #: did the optimiser itself stop by its criterion (``converged`` also needs the checks)
    optimiser_converged: bool = False
    #: fast method: (pose, evaluation) at the result, reused by the covariance
    _evaluation: tuple | None = field(default=None, repr=False, compare=False)

    def weakest_rotation_axis(self) -> np.ndarray | None:
        """Unit axis (world) of the turn the outlines constrain least, translation free to
        follow (smallest eigenvalue of the rotation block's Schur complement)."""
        H = self.normal_matrix
        if H is None:
            return None
        try:
            S = H[3:, 3:] - H[3:, :3] @ np.linalg.solve(H[:3, :3], H[:3, 3:])
        except np.linalg.LinAlgError:
            return None
        return np.linalg.eigh(S)[1][:, 0]

    def to_dict(self) -> dict:
        return {
            "pose": [float(v) for v in self.pose],
            "objective_mm": float(self.objective_mm),
            "per_view_mean_mm": [float(v) for v in self.per_view_mean_mm],
            "calls": int(self.calls),
            "seconds": float(self.seconds),
            "converged": bool(self.converged),
            "method": self.method,
            "cancelled": bool(self.cancelled),
            "message": self.message,
            "sd": None if self.sd is None else [float(v) for v in self.sd],
            "settings": self.settings,
        }


@dataclass
class MatchProblem:
    """One component in one frame: its mesh, the views and the image outline splines.

    ``occluded`` optionally gives, per view, a boolean image mask (or None) of where
    another component hides this one's outline: the fast method leaves out the model and
    image outline points that fall there (their image edges belong to the other
    component, or are missing)."""

    mesh: PreparedMesh
    views: Sequence[View]
    splines: Sequence  # OutlineSpline per view
    occluded: Sequence | None = None
    _cloud: dict = field(default_factory=dict, repr=False)

    def occluder(self, view_index: int) -> np.ndarray | None:
        if self.occluded is None or view_index >= len(self.occluded):
            return None
        return self.occluded[view_index]

    def cloud(self, n: int, seed: int = 0) -> np.ndarray:
        if (n, seed) not in self._cloud:
            self._cloud[(n, seed)] = sample_surface(self.mesh.vertices, self.mesh.faces, n, seed)
        return self._cloud[(n, seed)]


# -- centroid parametrisation ---------------------------------------------------------------
def _to_state(pose: np.ndarray, centroid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R = rotation_matrix(*pose[3:])
    return R, R @ centroid + pose[:3]


def _to_pose(R: np.ndarray, c: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    return np.array([*(c - R @ centroid), *angles_from_matrix(R)])


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


def _match_paper(problem, start, settings, progress, cancel) -> MatchResult:
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
        if cancel is not None and cancel():
            raise MatchCancelled
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

    cancelled = False
    message = ""
    try:
        # jac=None: forward differences with the absolute step `eps` (mm, degrees)
        out = optimize.minimize(f, x0, method="BFGS", jac=None, callback=callback,
                                options={"eps": settings.fd_step, "gtol": 0.0, "maxiter": 10_000})
        message = "" if converged[0] else f"BFGS stopped: {out.message}"
    except MatchCancelled:
        cancelled, message = True, "cancelled"
    except _CallLimit:
        message = "call limit reached"
    _, x_best, per_view = best
    if per_view is None:
        per_view = [float(v.mean()) for v in paper_view_distances(problem, pose_of(x_best), settings)]
    return MatchResult(pose_of(x_best), float(sum(per_view)), per_view, calls[0], 0.0,
                       converged[0] and not cancelled, "paper", settings.to_dict(), cancelled,
                       "" if converged[0] and not cancelled else message, history)


# -- the fast method ----------------------------------------------------------------------------
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


#: a view keeps all its outline points when fewer than this many are outside the occluded area
MIN_VISIBLE_POINTS = 8


def mask_at(mask: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """A boolean image's value at points (K, 2) in pixels (nearest pixel; False off the image)."""
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    h, w = mask.shape
    col = np.round(uv[:, 0]).astype(int)
    row = np.round(uv[:, 1]).astype(int)
    on = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    out = np.zeros(len(uv), dtype=bool)
    out[on] = mask[row[on], col[on]]
    return out


def visible_points(mask: np.ndarray | None, uv: np.ndarray) -> np.ndarray:
    """True for points (K, 2) in pixels that a boolean ``mask`` does not cover (points off
    the image count as visible); all True without a mask or when almost nothing is left."""
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    if mask is None or len(uv) == 0:
        return np.ones(len(uv), dtype=bool)
    visible = ~mask_at(mask, uv)
    return visible if visible.sum() >= MIN_VISIBLE_POINTS else np.ones(len(uv), dtype=bool)


class _FastEvaluation:
    """Residuals and Jacobian of the fast objective at one pose (correspondences frozen)."""

    def __init__(self, problem: MatchProblem, R, c, settings: MatchSettings, image_samples, image_params=None):
        mesh = problem.mesh
        t = c - R @ mesh.centroid
        rho = mesh.radius
        self.per_view_mm: list[float] = []
        self.outlines_px: list[np.ndarray] = []
        self.r, self.J, self.w = [], [], []
        # per residual block: its view and where along the image outline (px of chord
        # length) each residual sits, for the covariance's clusters of neighbours
        self.view_of: list[int] = []
        self.where: list[np.ndarray | None] = []
        for k, (view, spline, g) in enumerate(zip(problem.views, problem.splines, image_samples)):
            mask = problem.occluder(k)
            if settings.outline_points:
                sil = mesh_silhouette(mesh, R, t, view, spacing_px=1.0)
                fwd = sil.resample(n=settings.outline_points)
            else:
                sil = fwd = mesh_silhouette(mesh, R, t, view, spacing_px=settings.model_spacing_px)
            # model outline points to the image spline: signed distance along the spline normal
            X = fwd.model_points @ R.T + t
            uv, Jp = view.project_jacobian(X)
            self.outlines_px.append(sil.points_px)
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
            self.per_view_mm.append(float(np.mean(dist)) * view.mm_per_px())
            self._add(np.einsum("ij,ij->i", normal, uv - closest_pt), np.einsum("ij,ijk->ik", normal, Jp), X, c, rho,
                      spline.weight_at(t_near))
            self.view_of.append(k)
            self.where.append(t_near)
            if settings.symmetric:
                # image outline samples to the model outline (the dense silhouette polyline)
                _, idx = cKDTree(sil.points_px).query(g)
                n_model = _polyline_normals(sil.points_px, idx)
                Xm = sil.model_points[idx] @ R.T + t
                uvm, Jm = view.project_jacobian(Xm)
                self._add(np.einsum("ij,ij->i", n_model, uvm - g), np.einsum("ij,ijk->ik", n_model, Jm), Xm, c, rho,
                          None if image_params is None else spline.weight_at(image_params[k]))
                self.view_of.append(k)
                self.where.append(None if image_params is None else image_params[k])
        self.objective_mm = float(sum(self.per_view_mm))

    def _add(self, r: np.ndarray, nJ: np.ndarray, X: np.ndarray, c: np.ndarray, rho: float,
             weights: np.ndarray | None = None) -> None:
        """Residual rows with d/d(delta_c [mm], omega*rho [mm]) for X' = exp(w)(X - c) + c + delta;
        each block (one view, one direction) sums to weight 1, shared by the outline's
        ``weight_at`` where it has weights."""
        dw = -_times_skew(nJ, X - c) / rho
        self.r.append(r)
        self.J.append(np.hstack([nJ, dw]))
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


def _initial_translation(problem: MatchProblem, R, c, image_samples, iterations: int = 3) -> np.ndarray:
    """Shift the centroid so the silhouette centroids meet the image-outline centroids."""
    mesh = problem.mesh
    for _ in range(iterations):
        A, b = [], []
        for view, g in zip(problem.views, image_samples):
            sil = mesh_silhouette(mesh, R, c - R @ mesh.centroid, view, scale=1.0, spacing_px=2.0)  # a centroid: coarse is enough
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
    n_samples = [settings.outline_points or max(16, int(s.length_px / settings.spacing_px)) for s in problem.splines]
    if whole:
        return [s.sample(n) for s, n in zip(problem.splines, n_samples)]
    samples = [s.sample(n, skip_gaps=settings.skip_gaps and len(s.gaps) > 0) for s, n in zip(problem.splines, n_samples)]
    return [g[visible_points(problem.occluder(k), g)] for k, g in enumerate(samples)]


def _match_fast(problem, start, settings, progress, cancel) -> MatchResult:
    mesh = problem.mesh
    R, c = _to_state(start, mesh.centroid)
    if settings.centre_first:  # whole outlines: centroids of closed curves
        c = _initial_translation(problem, R, c, _image_samples(problem, settings, whole=True))
    image_samples = _image_samples(problem, settings)
    # where each image sample sits along its outline (for the covariance's stretches)
    image_params = [sp.closest(g)[3] if len(g) else np.zeros(0) for sp, g in zip(problem.splines, image_samples)]
    calls = 0
    history: list[float] = []
    lam = 1e-3
    huber = settings.huber_px
    ev = _FastEvaluation(problem, R, c, settings, image_samples, image_params)
    calls += 1
    cost = ev.robust_cost(huber)
    history.append(ev.objective_mm)
    converged = False
    cancelled = False
    while calls < settings.max_calls:
        if cancel is not None and cancel():
            cancelled = True
            break
        H, g = ev.normal_equations(huber)
        step = np.linalg.solve(H + lam * np.diag(np.diag(H) + 1e-9), -g)
        dc, w = step[:3], step[3:] / mesh.radius
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
            # the change of the variables we move: centroid (mm) and rotation (deg)
            move = np.r_[np.abs(dc), np.degrees(np.abs(w))]
            if np.all(move < settings.xtol):
                converged = True
                break
        else:
            # a rejected step this small is the objective's noise floor (the outline point
            # set changes from pose to pose): more damping would only spend evaluations
            move = np.r_[np.abs(dc), np.degrees(np.abs(w))]
            if np.all(move < 10 * settings.xtol):
                converged = True
                break
            lam *= 10.0
            if lam > 1e8:
                converged = bool(np.all(np.abs(step) < 10 * settings.xtol))
                break
    pose = _to_pose(R, c, mesh.centroid)
    return MatchResult(pose, ev.objective_mm, ev.per_view_mm, calls, 0.0, converged and not cancelled,
                       "fast", settings.to_dict(), cancelled,
                       "" if converged else ("cancelled" if cancelled else "did not converge"), history,
                       ev.normal_equations(huber)[0], ev.outlines_px, _evaluation=(pose, ev))


# -- uncertainty ---------------------------------------------------------------------------------
#: length (px along the image outline) of the stretches whose residuals are taken as one
#: independent unit: neighbouring outline points share edge noise, blur and segmentation
#: (measured on outlines with noise correlated over ~4 px: 24 px stretches still gave SDs
#: 0.7x the observed spread, 48 px 0.73-1.34x; tests/core/test_matching_uncertainty.py)
CLUSTER_PX = 48.0
#: ... but at least this many stretches per view (small outlines)
MIN_STRETCHES = 8


def pose_covariance(problem: MatchProblem, pose, settings: MatchSettings | None = None,
                    cluster_px: float = CLUSTER_PX, evaluation: tuple | None = None) -> np.ndarray:
    """Covariance (6x6; mm and degrees) of the pose variables x, y, z, alpha, beta, gamma.

    Gauss-Newton (Laplace) at ``pose`` with the residuals' own variance, as a sandwich
    H^-1 B H^-1: H is the Gauss-Newton matrix of the fast objective and B sums the
    gradient contributions of the residuals in stretches of ``cluster_px`` of image
    outline (both directions of residual in one stretch together), so residuals that are
    correlated along the outline (blur, segmentation, a systematic misfit) count as one
    sample per stretch instead of one per point. Infinite where the outlines do not fix
    a direction of motion."""
    settings = replace(settings or MatchSettings(), method="fast")
    mesh = problem.mesh
    pose = as_pose(pose)
    R, c = _to_state(pose, mesh.centroid)
    if evaluation is not None and np.allclose(evaluation[0], pose, rtol=0, atol=1e-12):
        ev = evaluation[1]  # the matcher's own last evaluation at this pose
    else:
        samples = _image_samples(problem, settings)
        params = [sp.closest(g)[3] if len(g) else np.zeros(0) for sp, g in zip(problem.splines, samples)]
        ev = _FastEvaluation(problem, R, c, settings, samples, params)
    H = np.zeros((6, 6))
    all_scores, all_keys, all_hessians = [], [], []
    for r, J, w, k, where in zip(ev.r, ev.J, ev.w, ev.view_of, ev.where):
        a = np.abs(r)
        ww = w * np.where(a <= settings.huber_px, 1.0, settings.huber_px / np.maximum(a, 1e-12))
        H += J.T @ (J * ww[:, None])
        all_scores.append(J * (ww * r)[:, None])
        all_hessians.append(np.einsum("ni,nj->nij", J, J * ww[:, None]))
        spline = problem.splines[k]
        length = min(cluster_px, spline.period / MIN_STRETCHES)
        stretch = np.floor((spline.wrap(where) - spline.t_range[0]) / length).astype(np.int64)
        all_keys.append(k * 1_000_000 + stretch)
    keys, group = np.unique(np.concatenate(all_keys), return_inverse=True)
    n = len(keys)
    eig = np.linalg.eigvalsh(H)
    if n <= 6 or eig[0] <= 1e-12 * max(eig[-1], 1e-300):
        return np.full((6, 6), np.inf)
    S = np.zeros((n, 6))
    np.add.at(S, group.ravel(), np.vstack(all_scores))
    Hg = np.zeros((n, 6, 6))
    np.add.at(Hg, group.ravel(), np.concatenate(all_hessians))
    # the jackknife over stretches (CR3): each stretch's own effect on the pose, with the
    # stretch left out of H. A plain sandwich H^-1 (sum s s^T) H^-1 is biased low when
    # there are few stretches for six variables (a single view: about a dozen).
    left_out = H[None] - Hg
    if np.any(np.linalg.eigvalsh(left_out)[:, 0] <= 1e-12 * max(eig[-1], 1e-300)):
        return np.full((6, 6), np.inf)  # one stretch alone fixes a direction of motion
    shifts = np.linalg.solve(left_out, S[..., None])[..., 0]  # (n, 6)
    cov = shifts.T @ shifts * (n - 1) / n
    # from the matcher's variables (centroid shift, rotation vector x radius) to the pose's
    A = np.zeros((6, 6))
    h = 1e-4
    for j in range(6):
        d = np.zeros(6)
        d[j] = h
        plus = _to_pose(rotvec_matrix(d[3:] / mesh.radius) @ R, c + d[:3], mesh.centroid)
        d[j] = -h
        minus = _to_pose(rotvec_matrix(d[3:] / mesh.radius) @ R, c + d[:3], mesh.centroid)
        A[:, j] = pose_difference(plus, minus) / (2 * h)
    return A @ cov @ A.T


def pose_sd(cov: np.ndarray) -> list[float]:
    """Standard deviations (mm, deg) from a pose covariance."""
    return [float(np.sqrt(v)) if np.isfinite(v) and v >= 0 else float("inf") for v in np.diag(cov)]


def match(problem: MatchProblem, start, settings: MatchSettings | None = None,
          progress: ProgressCallback | None = None, cancel: Callable[[], bool] | None = None) -> MatchResult:
    """Find the pose of ``problem``'s component from ``start`` (mm, degrees)."""
    settings = settings or MatchSettings()
    start = as_pose(start)
    if settings.method not in ("fast", "paper"):
        raise ValueError(f"unknown method {settings.method!r} (use 'fast' or 'paper')")
    settings.validate()
    runner = _match_fast if settings.method == "fast" else _match_paper
    t0 = time.perf_counter()
    rng = np.random.default_rng(settings.seed)
    best: MatchResult | None = None
    total_calls = 0
    for k in range(max(1, settings.starts)):
        s = start.copy()
        if k > 0:
            s[:3] += rng.normal(0, settings.restart_sd[0], 3)
            s[3:] += rng.normal(0, settings.restart_sd[1], 3)
        res = runner(problem, s, settings, progress, cancel)
        total_calls += res.calls
        if best is None or (res.objective_mm < best.objective_mm and not res.cancelled):
            best = res
        if res.cancelled:
            best.cancelled = True
            break
    best.calls = total_calls
    best.optimiser_converged = best.converged
    if not best.cancelled:
        _judge(problem, best, settings)
    best.seconds = time.perf_counter() - t0
    return best


def _judge(problem: MatchProblem, result: MatchResult, settings: MatchSettings) -> None:
    """The result's uncertainty and its own evidence (``core.quality.check_match``): a
    result that fails a check is not converged, and says why in ``message``."""
    from .quality import check_match  # quality builds on this module

    try:
        result.sd = pose_sd(pose_covariance(problem, result.pose, settings, evaluation=result._evaluation))
    except ValueError:  # the model behind a source at this pose
        result.sd = [float("inf")] * 6
    problems = check_match(problem, result)
    if problems:
        result.converged = False
        result.message = "; ".join(([result.message] if result.message else []) + problems)
