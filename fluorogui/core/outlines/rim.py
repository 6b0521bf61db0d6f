"""Where the silhouette really is when the metal thins at its rim.

Canny puts an edge at the steepest intensity change. Behind a metal component the image
is ``exp(-mu L)``, with ``L`` the path length through the metal, and near the silhouette
of a smooth surface ``L`` grows only like the square root of the distance inside it: the
intensity falls over a few tenths of a pixel *inside* the outline, and the blurred
edge's steepest point sits there too. On images made by an independent X-ray model
(``fluorogui.reference.xray``) the Canny outline of a cobalt-chrome component
(``mu`` ~1/mm) lies 0.05-0.5 px inside the true silhouette, more where the metal is thin
or gently curved; the matcher then puts the component too far from the source and turns
it to fit, 0.06-0.1 mm and 0.2-0.3 degrees off. A step-edged (filled) silhouette, the
old validation images, shows no such bias, which is why it went unseen.

This module moves every outline point to the boundary that explains the image around it:

1. At the matched pose, the model's own path length profile ``L_i(x)`` is cast along
   the model outline's outward normal at the point (rays from the source through the
   mesh, ``core.projection.path_length.path_lengths``): how the metal thickens with the distance ``x`` inside.
2. The pixels around the point (exact pixel values, no interpolation) are compared
   with ``(B + G s)(1 - t) + O t``, ``t = blur_sigma[1 - exp(-mu L_i(s0 - s))]``, for
   candidate boundary positions ``s0`` along the normal: ``B`` the background, ``G`` its
   slope across the edge, ``O`` what shines through the metal, solved per point by least
   squares, ``s0`` by a grid and a parabola. Two terms keep a 1-D profile true to a 2-D
   image: the blur of the sloped background times the shadow (``G sigma^2 dt/dx``), and
   the outline's bend (a pixel beside the normal lies ``t^2 kappa / 2`` further out, and
   the blur moves a bent edge ``sigma^2 kappa / 2`` inwards). Without them the refined
   outline of a femur on the X-ray model's leg lay 0.02-0.03 px inside the silhouette.
3. The attenuation ``mu`` and the blur ``sigma`` are the same for a whole image: they
   are chosen (``fit_rim_model``) as the pair whose best ``s0`` per point leaves the
   least residual over a subset of points (a coarse grid, then a finer one about its
   best), except that a sharp profile within 0.5 % of
   it wins (a pure step is one of the candidates): blur and a short ramp trade off
   against each other, and a sharp edge must keep its place. The fit is made again
   over more points without the strays of point 5.
4. The moves are smoothed along the outline (a median): the bias changes slowly along
   it, the noise of a single fit does not.
5. Points that land far from the rest (another edge beside the component's pulls whole
   stretches by a pixel or two) are left out of the outline.
6. Each point gets a weight for the match (``precision_weights``): the inverse variance
   of the fits about it, measured as their scatter. Where the metal thins gently the
   profile's minimum is shallow and the fits scatter three times as far as on a steep
   rim; with even weights those stretches set the pose's noise.

A bone's edge within a few pixels outside the outline is part of the model instead
(``core.outlines.second_edge``): found on the image's outer profile, its light ``exp(-k sqrt)``
multiplies the background of the points beside it.

The profile shape comes from the mesh at the current pose, so the refinement runs in the
automatic outline loop's later passes (``core.matching.loop``, where the refined outline is
kept only if it fits the model better than the plain one), never on reviewed outlines.
On the X-ray model the refined outline lies within about 0.05 px of the silhouette on
average. Real images (edge enhancement, scatter, an unknown display curve) are not yet
shown to follow the model, and the ones we have fit as a step edge, so by default the
loop first judges each view's edge with a quick fit (``edge_model``, ``is_soft``) and
refines only soft ones: a step edge stays where Canny puts it.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import cKDTree

from fluorogui.core.outlines.profile_fit import (
    least_squares,
    outline_curvature,
    precision_weights,
    smooth_along,
    strays,
)
from fluorogui.core.outlines.second_edge import REACH_PX as SECOND_EDGE_REACH_PX
from fluorogui.core.outlines.second_edge import edge_shape, second_edges
from fluorogui.core.outlines.spline import outward_normals, simple_or_plain
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.projection.path_length import ProjectedMesh, path_lengths, project_mesh
from fluorogui.core.projection.pose import rotation_matrix
from fluorogui.core.projection.silhouette import mesh_silhouette
from fluorogui.core.threads import each_view

#: candidate attenuations (1/mm; the last one is a step) and blurs (px, Gaussian sigma
#: including the pixel's own width)
MU_GRID = (0.2, 0.35, 0.5, 0.7, 1.0, 1.4, 2.0, 3.0, 5.0, 50.0)
SIGMA_GRID = (0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5)
_FINE = 0.05  # px: the grid the profiles are computed and blurred on
_X = np.arange(-8.0, 12.0, _FINE) + _FINE / 2  # inward distance from the boundary (px), off 0 by half a step
# where path lengths are cast (px inside the model boundary): finely near it, where
# the metal thickens fastest, coarsely beyond the pixels a fit uses
_L_OFFSETS = np.r_[0.0, 0.005, 0.01, 0.02, 0.035, 0.05, 0.075, np.arange(0.1, 1.0, 0.1),
                   np.arange(1.0, 7.0 + 1e-9, 0.25)]
# linear interpolation of a path length profile at _X (beyond the last offset: constant)
_LI0 = np.clip(np.searchsorted(_L_OFFSETS, np.clip(_X, 0, None), side="right") - 1, 0, len(_L_OFFSETS) - 2)
_LFRAC = np.clip((np.clip(_X, 0, None) - _L_OFFSETS[_LI0]) / np.diff(_L_OFFSETS)[_LI0], 0.0, 1.0)
_REACH, _LATERAL = 4.0, 1.0  # pixels used per point: along the normal and across it
# candidate boundary positions about the point (px), and the largest move a fit may make:
# thin metal (0.2/mm) puts Canny's edge up to 2.8 px inside the silhouette; with the
# old limits (2.5 and 2 px) those points were left out, the flange tips with them, and
# the femur's pose was 0.43 deg off without noise (0.015 deg now; ad-hoc measurement)
SEARCH_INWARD_PX, MAX_MOVE_PX = 4.0, 3.5
_SEARCH = np.arange(-1.0, SEARCH_INWARD_PX + 1e-9, 0.05)


@dataclass
class RimModel:
    """An image's attenuation (1/mm) and blur (px) as the boundary fit sees them."""

    mu: float
    sigma: float


#: what a refinement without enough points to fit assumes: a sharp edge (it moves nothing)
STEP = RimModel(MU_GRID[-1], 0.8)


# -- the boundary fit -------------------------------------------------------------------------
@dataclass
class _Points:
    """Per outline point: the pixels around it (signed distance along the normal from the
    model boundary, value, weight), the model's path lengths inwards, and where the
    point sits along the normal."""

    s: np.ndarray  # (P, W) px, + outwards, measured from the model boundary
    value: np.ndarray  # (P, W)
    weight: np.ndarray  # (P, W) 1 for pixels used
    lengths: np.ndarray  # (P, len(_L_OFFSETS)) mm
    at: np.ndarray  # (P,) the outline point's own position along the normal (px)
    blocked: np.ndarray  # (P, W) 1 for pixels under the exclusion mask
    edge: np.ndarray  # (P,) px from the model boundary to a second edge outside (NaN: none near)
    edge_k: np.ndarray  # (P,) how dark that edge is (``second_edge.edge_shape``)
    bend: np.ndarray  # (P,) the model outline's curvature at the point (1/px, + convex)


#: the last few results of ``_gather``: judging a view's rim, fitting it with the other
#: views' and refining its outline gather the same points at the same pose
_GATHERED: list = []
_GATHERED_LOCK = threading.Lock()


def _gather(image, view, mesh, pose, *, points, exclude=None) -> tuple[_Points, np.ndarray]:
    """What the fit needs of each outline point, and the model's outward normal (P, 2)
    along which it moves (read-only arrays: the same inputs give the same object)."""
    pose, points = np.asarray(pose, dtype=float), np.asarray(points, dtype=float)
    key = (image, view, mesh, exclude)
    with _GATHERED_LOCK:
        for entry in _GATHERED:
            if all(a is b for a, b in zip(entry[0], key)) and np.array_equal(entry[1], pose) \
                    and np.array_equal(entry[2], points):
                return entry[3]
    result = _gather_uncached(np.asarray(image, dtype=float), view, mesh, pose, points=points, exclude=exclude)
    for array in (*vars(result[0]).values(), result[1]):
        array.flags.writeable = False
    with _GATHERED_LOCK:
        _GATHERED.insert(0, (key, pose.copy(), points.copy(), result))
        del _GATHERED[6:]
    return result


@dataclass(frozen=True)
class _Posed:
    """The model at one pose in one view, as every gather there uses it: its outline
    (every 0.5 px), the outline's outward normals and curvature, a tree to find the
    nearest outline point, and the mesh projected for the path lengths."""

    outline: np.ndarray  # (Q, 2) px
    normals: np.ndarray  # (Q, 2)
    bend: np.ndarray  # (Q,) 1/px
    tree: cKDTree
    projected: ProjectedMesh


#: the last ``_Posed``, one per view of a component (a femur's is some 7 MB): the rim
#: judgement's sparse and full gathers, and the refinement's, ask at the same pose for
#: different points
_POSED: list = []
_POSED_KEPT = 2


def _posed(view, mesh, pose: np.ndarray) -> _Posed:
    """The model at ``pose`` in ``view`` (made once per view, mesh and pose)."""
    with _GATHERED_LOCK:
        for entry in _POSED:
            if entry[0] is view and entry[1] is mesh and np.array_equal(entry[2], pose):
                return entry[3]
    outline = mesh_silhouette(mesh, rotation_matrix(*pose[3:]), pose[:3], view).resample(spacing_px=0.5).points_px
    normals = outward_normals(outline)
    posed = _Posed(outline, normals, outline_curvature(outline, normals), cKDTree(outline),
                   project_mesh(mesh, pose, view))
    with _GATHERED_LOCK:
        _POSED.insert(0, (view, mesh, pose.copy(), posed))
        del _POSED[_POSED_KEPT:]
    return posed


def _gather_uncached(image, view, mesh, pose, *, points, exclude) -> tuple[_Points, np.ndarray]:
    posed = _posed(view, mesh, pose)
    _, nearest = posed.tree.query(points)
    m, n = posed.outline[nearest], posed.normals[nearest]
    bend = posed.bend[nearest]
    at = np.einsum("ij,ij->i", points - m, n)
    inward = m[:, None, :] - _L_OFFSETS[None, :, None] * n[:, None, :]
    lengths = path_lengths(mesh, pose, view, inward.reshape(-1, 2),
                           projected=posed.projected).reshape(len(points), -1)
    r = int(np.ceil(np.hypot(_REACH, _LATERAL))) + 1
    du, dv = np.meshgrid(np.arange(-r, r + 1), np.arange(-r, r + 1))
    cols = np.round(points[:, 0]).astype(int)[:, None] + du.ravel()[None, :]
    rows = np.round(points[:, 1]).astype(int)[:, None] + dv.ravel()[None, :]
    h, w = image.shape[:2]
    valid = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    value = np.asarray(image, dtype=float)[np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)]
    rel_u, rel_v = cols - points[:, :1], rows - points[:, 1:]
    s_point = rel_u * n[:, :1] + rel_v * n[:, 1:]  # along the normal from the outline point
    t_point = -rel_u * n[:, 1:] + rel_v * n[:, :1]
    used = valid & (np.abs(s_point) <= _REACH) & (np.abs(t_point) <= _LATERAL)
    # keep only the used pixels, packed to the left (the fit's cost grows with the width)
    order = np.argsort(~used, axis=1, kind="stable")[:, :int(used.sum(1).max())]
    pick = lambda a: np.take_along_axis(a, order, axis=1)
    # a pixel beside the normal lies further out than its distance along it where the
    # boundary bends away: by t^2 kappa / 2 at t px across
    s_used = pick(s_point + 0.5 * bend[:, None] * t_point ** 2) + at[:, None]
    blocked = np.zeros(value.shape)
    if exclude is not None:
        blocked = np.asarray(exclude)[np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)].astype(float)
    found, edge_k = second_edges(image, points, n, exclude)
    edge = at + found
    edge[~(found <= SECOND_EDGE_REACH_PX)] = np.nan
    return _Points(s_used, pick(value), pick(used).astype(float), lengths, at, pick(blocked), edge, edge_k, bend), n


_INSIDE = _X > 0  # where a deficit profile can be other than zero


@lru_cache(maxsize=32)
def _blur_inside(sigma: float) -> np.ndarray:
    """The Gaussian blur of ``sigma`` px (ends held, as scipy's "nearest") of a profile on
    ``_X`` that is zero outside the boundary, as a matrix from its inside samples to all
    of ``_X``: one product in place of a filter per point (8 ms -> 0.6 ms over 120 points)."""
    return gaussian_filter1d(np.eye(len(_X))[_INSIDE], sigma / _FINE, axis=1, mode="nearest")


def _templates(lengths: np.ndarray, mu: float, sigma: float) -> np.ndarray:
    """Blurred deficit profiles (P, len(_X)): 0 far outside, 1 - exp(-mu L) inside."""
    return _deficits(_inside_lengths(lengths), mu) @ _blur_inside(float(sigma))


def _inside_lengths(lengths: np.ndarray) -> np.ndarray:
    """The path length profiles (P, len(_L_OFFSETS)) at the inside samples of ``_X``."""
    return lengths[:, _LI0[_INSIDE]] * (1.0 - _LFRAC[_INSIDE]) + lengths[:, _LI0[_INSIDE] + 1] * _LFRAC[_INSIDE]


def _deficits(inside_lengths: np.ndarray, mu: float) -> np.ndarray:
    """The unblurred deficit 1 - exp(-mu L) at the inside samples."""
    return 1.0 - np.exp(-mu * inside_lengths)


@dataclass
class _Candidates:
    """What the profile fit (``_fit_residuals``) needs of the points that no rim model
    changes, computed once for a whole grid of models."""

    s0: np.ndarray  # (P, S) candidate boundaries along the normal, from the model boundary
    flat: np.ndarray  # (P, S, W) each pixel's template sample below it (flat index into (P, len(_X)))
    frac: np.ndarray  # (P, S, W) and how far on to the next
    flat_next: np.ndarray  # flat + 1
    frac_rest: np.ndarray  # 1 - frac
    weight: np.ndarray  # (P, 1, W)
    value: np.ndarray  # (P, 1, W) weighted
    s_rel: np.ndarray  # (P, 1, W) px along the normal from the outline point
    near: np.ndarray  # indices of the points with a second edge near
    shapes: dict  # sigma -> the bone edge's profile at the near points (``edge_shape``) and its slope outwards
    inside_lengths: np.ndarray  # the points' path lengths at the inside samples (``_inside_lengths``)
    deficits: dict  # mu -> their unblurred deficits (``_deficits``): a grid's blurs share them


def _candidates(pts: _Points, search: np.ndarray = _SEARCH) -> _Candidates:
    P = len(pts.at)
    s0 = pts.at[:, None] + search[None, :]  # (P, S) boundary candidates from the model boundary
    x = s0[:, :, None] - pts.s[:, None, :]  # (P, S, W) inward distance of each pixel
    idx = (x - _X[0]) / _FINE
    i0 = np.clip(np.floor(idx).astype(int), 0, len(_X) - 2)
    frac = np.clip(idx - i0, 0.0, 1.0)
    flat = i0 + (np.arange(P) * len(_X))[:, None, None]
    weight = pts.weight[:, None, :]
    return _Candidates(s0, flat, frac, flat + 1, 1 - frac, weight, pts.value[:, None, :] * weight,
                       (pts.s - pts.at[:, None])[:, None, :], np.flatnonzero(np.isfinite(pts.edge)), {},
                       _inside_lengths(pts.lengths), {})


def _residuals(pts: _Points, mu: float, sigma: float, search: np.ndarray = _SEARCH) -> tuple[np.ndarray, np.ndarray]:
    """For every point and candidate boundary (relative to the point): the least-squares
    residual of ``value ~ (B + G s) bone (1 - template) + O template`` (B, G, O free,
    O < B; ``bone`` the light a second edge outside lets through, ``_Points.edge``, 1
    where none lies near). Returns (P, S) residuals and the candidate positions along the
    normal (P, S)."""
    return _fit_residuals(pts, _candidates(pts, search), mu, sigma)


def _fit_residuals(pts: _Points, c: _Candidates, mu: float, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """``_residuals`` for the candidates ``c`` of ``pts``."""
    if mu not in c.deficits:
        c.deficits[mu] = _deficits(c.inside_lengths, mu)
    T = c.deficits[mu] @ _blur_inside(float(sigma))  # (``_templates``)
    T_in = np.gradient(T, _FINE, axis=1).ravel()  # how the template grows inwards (per px)
    T = T.ravel()
    t = np.take(T, c.flat) * c.frac_rest + np.take(T, c.flat_next) * c.frac
    t_in = np.take(T_in, c.flat) * c.frac_rest + np.take(T_in, c.flat_next) * c.frac
    # value ~ (B + G s)(1 - t) + O t: a background with a slope across the edge, dimmed
    # by the metal, and what comes through the metal (scatter, glare) deep inside it.
    # The blur of the sloped background times the metal's shadow adds G sigma^2 dt/dx
    # (exact for a Gaussian blur): left out, a background brightening outwards looks like
    # an edge further in (0.02 px inside on the X-ray model's leg, the attenuation 8 % high)
    outside = 1 - t
    basis = [outside * c.weight, (c.s_rel * outside + sigma ** 2 * t_in) * c.weight, t * c.weight]
    residual, coef = least_squares(basis, c.value)
    darker = coef[..., 2] < coef[..., 0]  # the metal is darker than its surround
    near = c.near
    if len(near):  # a bone's edge beside the rim: its profile is part of the background
        sub = [b[near] for b in basis]
        # (B + G s) bone(s) (1 - t) + O t, bone = exp(-k sqrt(edge - s)): the bone's k
        # measured beside the rim (``second_edges``), no further free number that the noise
        # could trade with s0. The blur of that background times the shadow adds
        # sigma^2 [(B + G s) bone]' dt/dx, as for the slope alone; left out, a bone 4 px
        # out pulled a tray's stretch 0.05 px inwards (``tests/core/test_second_edge.py``)
        if sigma not in c.shapes:
            inside, k = pts.edge[near, None] - pts.s[near], pts.edge_k[near]  # px inside the bone's edge
            shape = edge_shape(inside, k, sigma)
            outwards = (edge_shape(inside - _FINE, k, sigma) - edge_shape(inside + _FINE, k, sigma)) / (2 * _FINE)
            c.shapes[sigma] = shape[:, None, :], outwards[:, None, :]
        bone, bone_slope = c.shapes[sigma]
        s, w = c.s_rel[near], c.weight[near]
        cross = sigma ** 2 * t_in[near] * w
        basis_b = bone * sub[0] + bone_slope * cross
        basis_g = bone * s * outside[near] * w + (bone + s * bone_slope) * cross
        res, coef3 = least_squares([basis_b, basis_g, sub[2]], c.value[near])
        residual[near], darker[near] = res, coef3[..., 2] < coef3[..., 0]
    residual = np.where(darker, residual, np.inf)
    return residual, c.s0


def _best_positions(residual: np.ndarray, s0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The candidate with the least residual per point, refined by a parabola; and that residual."""
    k = np.argmin(residual, axis=1)
    rows = np.arange(len(k))
    best = residual[rows, k]
    kk = np.clip(k, 1, residual.shape[1] - 2)
    a, b, c = residual[rows, kk - 1], residual[rows, kk], residual[rows, kk + 1]
    usable = np.isfinite(a) & np.isfinite(b) & np.isfinite(c) & (k == kk)
    a, b, c = (np.where(usable, x, 0.0) for x in (a, b, c))  # no inf - inf below
    den = a - 2 * b + c
    usable &= den > 0
    shift = np.where(usable, 0.5 * (a - c) / np.where(usable, den, 1.0), 0.0)
    return s0[rows, kk] + np.clip(shift, -1, 1) * (s0[0, 1] - s0[0, 0]), best


def fit_rim_model(pts: _Points, max_points: int = 120, tolerance: float = 0.005,
                  sigma_grid: tuple = SIGMA_GRID) -> RimModel:
    """The image's (mu, sigma) from the grids: the pair whose best boundaries leave the
    least total residual over (up to ``max_points`` evenly spread) points - except that
    where a sharp profile (``SOFT_BELOW_MU`` or more) is within ``tolerance`` (relative)
    of that least residual, the sharpest such is kept. A little more blur and a short
    ramp explain a sharp edge about equally well, and the ramp would move the edge
    outwards. Among soft profiles there is no such jump: on noisy cobalt-chrome (1/mm)
    it took 1.4/mm where the least residual lay at 1.1 in 3 of 12 views, and moved a
    femur 0.02 deg (``tests/core/test_rim.py``)."""
    return fit_rim_models([pts], max_points, tolerance, sigma_grid)[0]


def fit_rim_models(views_pts: list[_Points], max_points: int = 120, tolerance: float = 0.005,
                   sigma_grid: tuple = SIGMA_GRID, *, below: float | None = None) -> list[RimModel]:
    """``fit_rim_model`` over the views of one component at once: one attenuation (the
    same metal in every view), chosen on the sum of the views' residual curves, each
    relative to its own least (its noise), and each view's blur where that lands. A
    noisy view's own attenuation varies by several per cent from draw to draw, and the
    views' outlines move the pose in opposite ways with it.

    ``below``: the caller asks only whether the attenuation is below this (``edge_models``'
    quick fit). Where every view's coarse curve fitted and even the top of the finer grid
    about the coarse vertex lies below it, the finer grid is not computed (its vertex
    stays within that grid, so it could only land below too) and the coarse estimate is
    returned: below as well, with blurs that are not the finer grid's. (The one way the
    finer grid could have said otherwise: no pair of it fitting a single point of the
    first view, whose model would then have fallen back to ``STEP``, where the coarse
    grid's pairs about the same attenuations did fit. At every frame's pose of the real
    biplane sequence, both components, the finer grid was skipped in 22 of 66 quick fits
    and every verdict was the whole fit's.)"""
    curves = each_view(lambda pts: _residual_per_mu(pts, max_points, sigma_grid), views_pts)  # side by side
    fitted = [c for c in curves if c is not None]
    if not fitted:
        return [STEP] * len(views_pts)
    total = sum(per_mu / per_mu.min() for per_mu, _ in fitted)
    best = int(np.argmin(total))
    i = int(np.flatnonzero(total <= total[best] * (1.0 + tolerance)).max())
    if i != best and MU_GRID[i] >= SOFT_BELOW_MU:  # a sharp profile explains the images as well
        return [RimModel(float(MU_GRID[i]), float(c[1][i])) if c is not None else STEP for c in curves]
    # between the grid's values: a parabola in log(mu), then the same on a finer grid about
    # it (the coarse grid's cells are 40 % wide and the curve is not a parabola over them:
    # cobalt-chrome at 1/mm fitted 1.06-1.09 from the coarse grid alone), and each view's
    # blur where it lands
    log_mu = _parabola_vertex(np.log(MU_GRID), total, best)[0]
    grid = np.log(MU_GRID)
    surely_below = (below is not None and all(c is not None for c in curves)
                    and np.exp((log_mu + FINE_LOG_MU_STEPS)[-1]) < below)
    if 0 < best < len(MU_GRID) - 1 and not surely_below:
        grid = log_mu + FINE_LOG_MU_STEPS
        curves = each_view(lambda pc: _residual_per_mu_near(pc[0], max_points, sigma_grid, tuple(np.exp(grid)),
                                                            sigma=pc[1][1][best]) if pc[1] is not None else None,
                           list(zip(views_pts, curves)))
        fitted = [c for c in curves if c is not None]
        total = sum(per_mu / per_mu.min() for per_mu, _ in fitted)
        best = int(np.argmin(total))
        log_mu = _parabola_vertex(grid, total, best)[0]
    near = slice(max(best - 1, 0), best + 2)
    return [RimModel(float(np.exp(log_mu)), float(np.interp(log_mu, grid[near], c[1][near])))
            if c is not None else STEP for c in curves]


#: the finer grid of ``fit_rim_models`` about the coarse grid's vertex (log 1/mm)
FINE_LOG_MU_STEPS = np.array([-0.1, -0.05, 0.0, 0.05, 0.1])


def _residual_per_mu(pts: _Points, max_points: int, sigma_grid: tuple,
                     mu_grid: tuple = MU_GRID) -> tuple[np.ndarray, np.ndarray] | None:
    """Per attenuation of the grid: the least total residual of the best boundaries over
    (up to ``max_points`` evenly spread) points, over the blurs (a parabola between the
    grid's), and the blur there; None when no pair fits any point."""
    sub = _subset(pts, slice(None, None, max(1, len(pts.at) // max_points)))
    candidates = _candidates(sub, _SEARCH[::2])
    costs = np.full((len(mu_grid), len(sigma_grid)), np.inf)
    for j, sigma in enumerate(sigma_grid):  # blur outside: the bone edge's profile depends on it alone
        for i, mu in enumerate(mu_grid):
            best = _best_positions(*_fit_residuals(sub, candidates, mu, sigma))[1]
            best = best[np.isfinite(best)]
            if len(best):  # a few points on other edges must not decide: cap each at 10x the median
                costs[i, j] = float(np.sum(np.minimum(best, 10.0 * np.median(best))))
    if not np.isfinite(costs).any():
        return None
    sigmas, per_mu = zip(*(_parabola_vertex(sigma_grid, row) for row in costs))
    return np.asarray(per_mu), np.asarray(sigmas)


def _residual_per_mu_near(pts: _Points, max_points: int, sigma_grid: tuple, mu_grid: tuple,
                          *, sigma: float) -> tuple[np.ndarray, np.ndarray] | None:
    """``_residual_per_mu`` over only the blurs of the grid within two steps of ``sigma``
    (the finer attenuations lie close to the coarse best, and so does their blur), or the
    whole grid where a least residual lands on that window's edge. Only the least sample
    and its neighbours shape the parabola, so this gives what the whole grid gives wherever
    the grid's least blur lies inside the window (the femur's refined outline the same to
    the last digit), with 25 fits in place of 60."""
    j = int(np.argmin(np.abs(np.asarray(sigma_grid) - sigma)))
    lo, hi = max(j - 2, 0), min(j + 3, len(sigma_grid))
    window = tuple(sigma_grid[lo:hi])
    result = _residual_per_mu(pts, max_points, window, mu_grid)
    # a blur on the window's edge (where the parabola puts a least there, or stops at it)
    if result is not None and ((lo > 0 and np.any(result[1] <= window[0]))
                               or (hi < len(sigma_grid) and np.any(result[1] >= window[-1]))):
        return _residual_per_mu(pts, max_points, sigma_grid, mu_grid)
    return result


def _parabola_vertex(x: np.ndarray, y: np.ndarray, k: int | None = None) -> tuple[float, float]:
    """Where the parabola through the samples k - 1, k, k + 1 (k: the least sample unless
    given) is lowest, kept between x[k - 1] and x[k + 1], and its value there; the sample
    itself at the ends, next to a value that is not finite, or when the three do not
    curve upwards."""
    y = np.asarray(y, dtype=float)
    k = int(np.argmin(y)) if k is None else k
    if not 0 < k < len(x) - 1 or not np.all(np.isfinite(y[k - 1:k + 2])):
        return float(x[k]), float(y[k])
    coef = np.polyfit(x[k - 1:k + 2], y[k - 1:k + 2], 2)
    if coef[0] <= 0:
        return float(x[k]), float(y[k])
    vertex = float(np.clip(-coef[1] / (2 * coef[0]), x[k - 1], x[k + 1]))
    return vertex, float(np.polyval(coef, vertex))


def refine_outline(image: np.ndarray, view: View, mesh: PreparedMesh, pose, *, outline_px: np.ndarray,
                   model: RimModel | None = None, exclude: np.ndarray | None = None,
                   smooth: int = 8) -> tuple[np.ndarray, RimModel]:
    """``outline_px`` (K, 2, ordered along a closed outline) moved along the model's
    normal to the boundary the rim profile fit finds, and the image's rim model (fitted
    here unless given). Each point moves by the median of the fitted moves of itself and
    its ``smooth`` neighbours either side; a fit does not count when it fails, when it
    would move its point by more than ``MAX_MOVE_PX``, or when a pixel it uses lies under
    ``exclude`` (a boolean image: another component, whose own edge would spoil it).
    Points that land far from the rest (``profile_fit.strays``) are left out of the result, and a
    result that crosses itself is mended or given up (``simple_or_plain``)."""
    outlines, models, _ = refine_outlines([image], [view], mesh, pose, outlines_px=[outline_px], models=[model],
                                          excludes=[exclude], smooth=smooth)
    return outlines[0], models[0]


def refine_outlines(images, views, mesh: PreparedMesh, pose, *, outlines_px, models=None, excludes=None,
                    smooth: int = 8) -> tuple[list[np.ndarray], list[RimModel], list[np.ndarray | None]]:
    """``refine_outline`` in each of a component's views; the views whose model is not
    given (None in ``models``) have theirs fitted together (``fit_rim_models``: one
    attenuation, each view's blur). Also returns each refined outline's point weights
    (``precision_weights``; None where nothing was refined), for ``OutlineSpline.fit``."""
    models = list(models) if models is not None else [None] * len(views)
    excludes = list(excludes) if excludes is not None else [None] * len(views)

    def gather(k: int) -> tuple:
        points = np.asarray(outlines_px[k], dtype=float).reshape(-1, 2)
        if len(points) < 8:
            return points, None, None, None
        pts, n = _gather(images[k], views[k], mesh, pose, points=points, exclude=excludes[k])
        return points, pts, n, _usable(pts)

    gathered = each_view(gather, range(len(outlines_px)))  # the views side by side, here and below
    for k, (_, pts, _, _) in enumerate(gathered):
        if pts is None:
            models[k] = models[k] or STEP
    to_fit = [k for k, (_, pts, _, _) in enumerate(gathered) if pts is not None and models[k] is None]
    if to_fit:
        fitted = _fit_models([gathered[k][1] for k in to_fit], [gathered[k][3] for k in to_fit], smooth)
        for k, model in zip(to_fit, fitted):
            models[k] = model

    def refine(k: int) -> tuple[np.ndarray, np.ndarray | None]:
        points, pts, n, usable = gathered[k]
        if pts is None:
            return points.copy(), None
        moves, offsets, found = _moves(pts, models[k], usable, smooth)
        drop = strays(offsets)
        if drop.mean() > MAX_DROPPED:  # too many to be strays: the pose is not close enough to judge
            drop[:] = False
        moved = (points + moves[:, None] * n)[~drop]
        outline = simple_or_plain(moved, points)
        if outline is not moved and np.array_equal(outline, points):
            return outline, None  # given up for Canny's own outline
        # each point (of an untangled outline too) weighted as the moved point it is
        return outline, precision_weights(found)[~drop][cKDTree(moved).query(outline)[1]]

    refined, weights = (list(x) for x in zip(*each_view(refine, range(len(gathered))))) if gathered else ([], [])
    return refined, models, weights


def rim_model(image: np.ndarray, view: View, mesh: PreparedMesh, pose, *, outline_px: np.ndarray,
              exclude: np.ndarray | None = None, smooth: int = 8, judging: bool = False) -> RimModel:
    """The image's rim model as ``refine_outline`` fits it (without moving anything);
    ``judging``: without the second fit where the first finds a step (``_fit_model``)."""
    points = np.asarray(outline_px, dtype=float).reshape(-1, 2)
    if len(points) < 8:
        return STEP
    pts, _ = _gather(image, view, mesh, pose, points=points, exclude=exclude)
    return _fit_model(pts, _usable(pts), smooth, judging)


def _fit_model(pts: _Points, usable: np.ndarray, smooth: int, judging: bool = False) -> RimModel:
    return _fit_models([pts], [usable], smooth, judging)[0]


def _fit_models(views_pts: list[_Points], usable: list[np.ndarray], smooth: int,
                judging: bool = False) -> list[RimModel]:
    """The images' models (one component's views, fitted together): a first fit over 120
    points per view and a second one over more points without the strays the first
    one's moves show (``judging``: only where the first is softer than
    ``MAYBE_SOFT_BELOW_MU``; a step edge is not refined, its blur not needed)."""
    enough = [k for k, u in enumerate(usable) if u.sum() >= 8]
    models = [STEP] * len(views_pts)
    if not enough:
        return models
    first = fit_rim_models([_subset(views_pts[k], usable[k]) for k in enough])
    for k, model in zip(enough, first):
        models[k] = model
    again = [k for k in enough if models[k] is not STEP and not (judging and models[k].mu >= MAYBE_SOFT_BELOW_MU)]
    # strays must not decide the images' model either: fit it again without them, over
    # more points (the attenuation of a first fit over 120 points varies by several per
    # cent from one noise draw to the next, and moves the outline with it)
    kept = dict(zip(again, each_view(lambda k: usable[k] & ~strays(_moves(views_pts[k], models[k], usable[k],
                                                                          smooth)[1]), again)))
    again = [k for k in again if kept[k].sum() >= 8]
    if again:
        for k, model in zip(again, fit_rim_models([_subset(views_pts[k], kept[k]) for k in again],
                                                  max_points=REFIT_POINTS)):
            models[k] = model
    return models


#: a fitted attenuation (1/mm) below this is a soft rim (``is_soft``). The X-ray model's
#: cobalt-chrome (1/mm) fits 1.0-1.4; the real biplane views 2-50 (76 of 106 the grid's
#: step of 50) but 3 of 106 at 1.0-1.4 (the full fit, ``rim_model``, at the listed poses
#: of every frame, ad hoc): a narrow margin (docs/methods/outlines.rst, When the loop refines)
SOFT_BELOW_MU = 1.7
#: the quick fit (``edge_model``) calls an edge a step above this, and the full fit decides
#: below it: it saw soft rims in 40 % of the real views the full fit calls steps, fits of
#: 5-8/mm on the demo's blurred step edges, and 1.0-1.4/mm on cobalt-chrome
MAYBE_SOFT_BELOW_MU = 4.0
#: outline points the quick fit of ``edge_model`` uses, and how much more residual (relative)
#: a sharper profile may leave and still win there: at 0.5 % a step edge on the X-ray
#: model fitted below 10/mm in 2 (60 points) or 3 (120 points) of 16 views (noise draws),
#: at 1 % over 120 points in none, while all 16 of cobalt-chrome (1/mm) fitted below 1.5
DECIDE_POINTS, DECIDE_TOLERANCE = 120, 0.01
#: the quick fit's blurs (px): coarse, but up to the real images' 1.5 (with 1.3 at most it
#: called half the real views soft) and fine enough near the demo's 0.85
DECIDE_SIGMAS = (0.4, 0.6, 0.8, 1.0, 1.25, 1.5)


def is_soft(model: RimModel) -> bool:
    """Whether an image's edge, as its full rim model (``rim_model``) describes it, is a
    soft rim: Canny's outline then lies inside the silhouette (more the softer it is), and
    the automatic loop refines it by default."""
    return model.mu < SOFT_BELOW_MU


def edge_model(image: np.ndarray, view: View, mesh: PreparedMesh, pose, *, outline_px: np.ndarray,
               exclude: np.ndarray | None = None) -> RimModel:
    """The image's rim model, quickly when that is enough: a quick fit over
    ``DECIDE_POINTS`` evenly spread outline points and a coarse blur grid (0.3-0.5 s per
    512 px view of the X-ray model) where it finds a step edge (attenuation
    ``MAYBE_SOFT_BELOW_MU`` or more), else the full fit of ``rim_model``: its first fit over
    120 points and, where that is not a step either, the second one (2.6-3.4 s in all)."""
    return edge_models([image], [view], mesh, pose, outlines_px=[outline_px], excludes=[exclude])[0]


def edge_models(images, views, mesh: PreparedMesh, pose, *, outlines_px, excludes=None) -> list[RimModel]:
    """``edge_model`` over the views of one component at once: one attenuation for its
    metal, chosen on the sum of the views' residual curves (as ``fit_rim_models``), each
    view's blur where that lands. A view's own quick fit swings between a soft rim and a
    step from frame to frame where its curve is flat between them (the X-ray model's tray
    with bone and cement beside it: 4 of the first 5 frames of a bend called view 2 a
    step, the truth 0.9/mm soft, and the kept step turned the tray 0.1 deg); the other
    view's curve, of the same metal, settles it. Where the quick fit is not a step, the
    full fit of the views together decides (soft views keep its shared attenuation). A
    view with too few usable points is a step."""
    excludes = list(excludes) if excludes is not None else [None] * len(views)

    def gather(k: int):
        points = np.asarray(outlines_px[k], dtype=float).reshape(-1, 2)
        sparse = points[::max(1, len(points) // DECIDE_POINTS)]
        if len(sparse) < 8:
            return None
        pts, _ = _gather(images[k], views[k], mesh, pose, points=sparse, exclude=excludes[k])
        usable = _usable(pts)
        return _subset(pts, usable) if usable.sum() >= 8 else None

    sparse = each_view(gather, range(len(views)))  # the views side by side
    fitted = [k for k, pts in enumerate(sparse) if pts is not None]
    models = [STEP] * len(views)
    if not fitted:
        return models
    quick = fit_rim_models([sparse[k] for k in fitted], max_points=DECIDE_POINTS, tolerance=DECIDE_TOLERANCE,
                           sigma_grid=DECIDE_SIGMAS, below=MAYBE_SOFT_BELOW_MU)  # only its verdict counts there
    if quick[0].mu >= MAYBE_SOFT_BELOW_MU:
        for k, model in zip(fitted, quick):
            models[k] = model
        return models
    full = each_view(lambda k: _gather(images[k], views[k], mesh, pose, exclude=excludes[k],
                                       points=np.asarray(outlines_px[k], dtype=float).reshape(-1, 2))[0], fitted)
    for k, model in zip(fitted, _fit_models(full, [_usable(pts) for pts in full], 8, judging=True)):
        models[k] = model
    return models


#: at most this share of an outline's points is left out as strays
MAX_DROPPED = 0.2
#: points (evenly spread) the second fit of a rim model uses
REFIT_POINTS = 300


def _moves(pts: _Points, model: RimModel, usable: np.ndarray,
           smooth: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each point's smoothed move along the normal (px) under ``model``, where it lands
    from the model boundary (NaN for points that are not ``usable``), and where its own
    fit put the boundary (NaN where the fit does not count)."""
    residual, s0 = _residuals(pts, model.mu, model.sigma)
    boundary, best = _best_positions(residual, s0)
    # the blur of a bent boundary looks like the straight one's moved inwards by
    # sigma^2 kappa / 2 (the kernel's spread across the normal meets the bend)
    boundary = boundary + 0.5 * pts.bend * model.sigma ** 2
    moved = boundary - pts.at
    keep = usable & np.isfinite(best) & (np.abs(moved) <= MAX_MOVE_PX)
    moves = smooth_along(np.where(keep, moved, np.nan), smooth)
    return moves, np.where(usable, pts.at + moves, np.nan), np.where(keep, boundary, np.nan)


def _usable(pts: _Points) -> np.ndarray:
    """The points none of whose pixels lies under the exclusion mask (another component)."""
    return ~np.any((pts.weight > 0) & (pts.blocked > 0), axis=1)


def _subset(pts: _Points, rows) -> _Points:
    return _Points(pts.s[rows], pts.value[rows], pts.weight[rows], pts.lengths[rows], pts.at[rows], pts.blocked[rows],
                   pts.edge[rows], pts.edge_k[rows], pts.bend[rows])
