"""Condylar contact kinematics: where each femoral condyle sits on the tibial component.

Everything is expressed in the tibial component's anatomical frame (x to the subject's
right, y anterior, z proximal, origin at the centre of the tray's top;
``core.knee.anatomy``), then mirrored for a left knee (x → −x) so that **+x is lateral on
both knees**, as left knees are mirrored into right ones by the kinematics.

* **Lowest point** (Banks & Hodge): the femoral surface is split into its medial and
  lateral condyles by the femoral component's own sagittal plane (the x = 0 plane of its
  anatomical frame); each condyle's point nearest the tibial plateau, lowest along the
  tibial z axis. On a triangle mesh the lowest point is always a vertex, which moves in
  steps of the mesh spacing, so the surface is fitted: a polynomial height ``z(x, y)``
  (quartic, or quadratic where few vertices are near) over the downward-facing vertices
  within a few mesh spacings, its minimum, the neighbourhood recentred there and fitted
  again (so that the neighbourhood is symmetric and the surface's higher-order terms do
  not shift the minimum).
* **Closest point to the insert** (Li's group): with an insert model placed on the tray
  (``place_insert``), the closest pair of points between each condyle and the insert,
  and their distance (the *gap*; negative where the condyle is behind a face of the
  insert, i.e. overlaps it; an open insert surface is taken to face up). The condyle's
  vertices that can be nearest are ranked by an upper bound of their distance, the
  ``SEEDS`` best measured exactly (``core.projection.nearest``) and the nearest kept; the
  femoral surface is fitted around it as for the lowest point and the gap, measured
  exactly to the insert's triangles from points of the fitted surface, is minimised.
* **Lift-off** (Dennis et al. 2001; Key et al. 2019): a condyle lifts off when its gap
  exceeds ``liftoff_mm`` (1.0 mm by default); without an insert, when it stands higher
  than the other condyle by more than ``liftoff_mm``.
* **Pivot** (Banks): the least-squares intersection of the lines through the medial and
  lateral points over the activity, in the tray's transverse plane. A femur turning about a
  vertical axis turns its medial–lateral line about the axis's foot on that line, which is
  the point found. Frames without both points, or whose points are closer than
  ``MIN_LINE_MM``, do not define a line and are left out; when the lines' directions
  spread less than ``MIN_SPREAD_DEG`` (RMS), the pivot is not determined.
* **Rollback**: each condyle's anterior–posterior position against flexion; its
  excursion is the position at the least flexion minus that at the greatest
  (positive: the condyle moved posteriorly as the knee flexed).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fluorogui.core.knee.kinematics import KinematicsError, check_side
from fluorogui.core.projection.nearest import TriangleSurface

LIFTOFF_MM = 1.0
CONDYLES = ("medial", "lateral")
#: medial and lateral points closer than this (in the transverse plane) define no line
MIN_LINE_MM = 10.0
#: the lines' directions must spread at least this much (RMS) to locate a pivot
MIN_SPREAD_DEG = 1.0
#: how far above a condyle's lowest vertex its vertices are searched for the closest point to an insert
INSERT_BAND_MM = 10.0
#: vertices measured exactly to the insert: those whose rough distance is within this (and
#: twice the insert's sampling cover) of the least
PRUNE_MM = 0.5
#: of those, the vertices nearest their nearest sample's triangle measured exactly
SEEDS = 64
#: the insert's closest-point samples lie this far apart at most: coarse samples build fast and,
#: for condyles millimetres away, fetch fewer candidates (the real tibial component as a
#: stand-in insert: 0.13 s of set-up instead of 4.6 s, 0.7 s a frame instead of 1.7 s, loaded)
INSERT_COVER_MM = 2.0
LIFTOFF_CHOICES = ("none", "medial", "lateral", "both")
CONTACT_SIGN_CONVENTIONS = (
    "points in the tibial component's anatomical frame, mm: x lateral + (the subject's right on a right knee; "
    "a left knee is mirrored, x -> -x, so + is lateral on both), y anterior +, z proximal + (height above the "
    "tray's top); medial and lateral condyles split by the femoral component's sagittal plane (its anatomical x = 0); "
    "x, y, z: each condyle's lowest point along the tibial z axis (Banks), on the fitted surface; "
    "gap: the closest distance from the condyle to the insert surface (negative: overlap); "
    "liftoff: a condyle whose gap exceeds the threshold (without an insert: standing higher than the other "
    "condyle by more than the threshold)"
)


@dataclass(frozen=True)
class FemoralSurface:
    """The femoral component prepared for contact: its mesh in the model frame, unit vertex
    normals pointing out of the material, which vertices lie on the subject's right of its
    sagittal plane, and the median edge length (mm)."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    right: np.ndarray
    spacing: float


@dataclass(frozen=True)
class Insert:
    """An insert (polyethylene) model placed on the tray, in the tibial anatomical frame
    (not mirrored), with its faces wound so that their normals point out of it."""

    surface: TriangleSurface


@dataclass(frozen=True)
class CondyleContact:
    """One condyle in one frame (tibial anatomical frame, mirrored for a left knee).

    Attributes
    ----------
    lowest : numpy.ndarray of shape (3,)
        The lowest point (mm).
    gap_mm : float
        Closest distance to the insert (negative: overlap); NaN without an insert.
    femoral_point, insert_point : numpy.ndarray of shape (3,)
        The closest pair of points (on the condyle, on the insert); NaN without an insert.
    """

    lowest: np.ndarray
    gap_mm: float = float("nan")
    femoral_point: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    insert_point: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))

    @classmethod
    def missing(cls) -> "CondyleContact":
        return cls(np.full(3, np.nan))


@dataclass(frozen=True)
class Contact:
    """Both condyles in one frame and the lift-off verdict (``LIFTOFF_CHOICES``, or "" when
    the frame has no values)."""

    medial: CondyleContact
    lateral: CondyleContact
    liftoff: str

    @classmethod
    def missing(cls) -> "Contact":
        return cls(CondyleContact.missing(), CondyleContact.missing(), "")


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals, turned to point out of a closed surface."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    cross = np.cross(b - a, c - a)
    if np.einsum("ij,ij->", a, cross) < 0:  # six times the signed volume: wound inwards
        cross = -cross
    normals = np.zeros_like(vertices)
    for i in range(3):
        np.add.at(normals, faces[:, i], cross)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)


def _check_mesh(vertices, faces, what: str) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise KinematicsError(f"the {what} mesh needs vertices (N, 3) and triangles (M, 3)")
    if f.min() < 0 or f.max() >= len(v) or not np.all(np.isfinite(v)):
        raise KinematicsError(f"the {what} mesh has bad vertices or faces")
    return v, f


def prepare_femur(vertices, faces, femoral_frame) -> FemoralSurface:
    """The femoral mesh (model frame) ready for contact, split by the sagittal plane of its
    anatomical frame ``femoral_frame`` (4×4, anatomical → model)."""
    v, f = _check_mesh(vertices, faces, "femoral")
    frame = np.asarray(femoral_frame, dtype=float)
    x_axis, origin = frame[:3, 0], frame[:3, 3]
    edges = np.linalg.norm(v[f[:, 0]] - v[f[:, 1]], axis=1)
    return FemoralSurface(v, f, _vertex_normals(v, f), (v - origin) @ x_axis > 0,
                          float(np.median(edges[edges > 0])) if np.any(edges > 0) else 1.0)


def place_insert(vertices, faces, tibial_frame, insert_to_tray=None) -> Insert:
    """An insert model on the tray: ``insert_to_tray`` (4×4, insert model → tibial model
    coordinates; identity by default) then the inverse of the tibial anatomical frame."""
    v, f = _check_mesh(vertices, faces, "insert")
    to_tray = np.eye(4) if insert_to_tray is None else np.asarray(insert_to_tray, dtype=float)
    placed = np.linalg.inv(np.asarray(tibial_frame, dtype=float)) @ to_tray
    v = v @ placed[:3, :3].T + placed[:3, 3]
    a, b, c = (v[f[:, i]] for i in range(3))
    cross = np.cross(b - a, c - a)
    # a closed surface's vector area is zero: wind it outwards; an open one (the articular
    # surface alone) faces up, towards the femur
    area = float(np.linalg.norm(cross, axis=1).sum())
    closed = float(np.linalg.norm(cross.sum(axis=0))) <= 1e-3 * area
    inward = np.einsum("ij,ij->", a - v.mean(axis=0), cross) < 0 if closed else cross[:, 2].sum() < 0
    return Insert(TriangleSurface(v, f[:, ::-1] if inward else f, cover=INSERT_COVER_MM))


def _frame_axes(k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``k`` to a right-handed orthonormal basis."""
    helper = np.array([1.0, 0, 0]) if abs(k[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(helper, k)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(k, e1)


QUADRATIC = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
#: up to the fourth order where the patch has the points for it: on a sphere of radius R a
#: quadratic fitted out to a distance r misses the height by a part of r^4 / (8 R^3)
QUARTIC = QUADRATIC + ((3, 0), (2, 1), (1, 2), (0, 3), (4, 0), (3, 1), (2, 2), (1, 3), (0, 4))


@dataclass(frozen=True)
class _Poly:
    """A polynomial ``h(u, v) = sum c_k (u/s)^i (v/s)^j`` (scaled by ``s`` for conditioning)."""

    powers: np.ndarray
    coef: np.ndarray
    scale: float


def _fit(uv: np.ndarray, h: np.ndarray) -> _Poly | None:
    """Least-squares polynomial ``h(u, v)``: quartic with 24 points or more, quadratic with
    8 or more, else None."""
    if len(h) < 8:
        return None
    powers = np.array(QUARTIC if len(h) >= 24 else QUADRATIC)
    scale = max(float(np.abs(uv).max()), 1e-9)
    s = uv / scale
    design = s[:, :1] ** powers[:, 0] * s[:, 1:] ** powers[:, 1]
    return _Poly(powers, np.linalg.lstsq(design, h, rcond=None)[0], scale)


def _value(poly: _Poly, at: np.ndarray) -> np.ndarray:
    s = np.asarray(at, dtype=float)[..., None, :] / poly.scale
    return (s[..., 0] ** poly.powers[:, 0] * s[..., 1] ** poly.powers[:, 1]) @ poly.coef


def _derivatives(poly: _Poly, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradient and Hessian of the polynomial at one point."""
    u, v = np.asarray(at, dtype=float) / poly.scale
    i, j, c = poly.powers[:, 0], poly.powers[:, 1], poly.coef

    def term(di, dj):  # d^(di+dj) / du^di dv^dj of the scaled monomials, summed
        fi = np.where(i >= di, 1.0, 0.0) * (i if di >= 1 else 1) * (np.maximum(i - 1, 0) if di >= 2 else 1)
        fj = np.where(j >= dj, 1.0, 0.0) * (j if dj >= 1 else 1) * (np.maximum(j - 1, 0) if dj >= 2 else 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            mono = np.power(u, np.maximum(i - di, 0)) * np.power(v, np.maximum(j - dj, 0))
        return float(np.sum(c * fi * fj * mono)) / poly.scale ** (di + dj)

    gradient = np.array([term(1, 0), term(0, 1)])
    hessian = np.array([[term(2, 0), term(1, 1)], [term(1, 1), term(0, 2)]])
    return gradient, hessian


def _minimum(poly: _Poly | None) -> np.ndarray | None:
    """Where the polynomial is least near the origin (Newton's method from the origin); None
    when it is not a bowl there."""
    if poly is None:
        return None
    at = np.zeros(2)
    for _ in range(20):
        gradient, hessian = _derivatives(poly, at)
        if np.linalg.eigvalsh(hessian)[0] <= 1e-9:
            return None
        step = np.linalg.solve(hessian, gradient)
        at = at - step
        if np.linalg.norm(step) < 1e-9 * poly.scale:
            break
    return at


def _surface_patch(points, normals, centre, axis, radius):
    """Local coordinates (u, v) and heights along ``axis`` of the vertices facing ``-axis``
    within ``radius`` of ``centre`` (across and along the axis)."""
    e1, e2 = _frame_axes(axis)
    rel = points - centre
    h = rel @ axis
    uv = np.column_stack([rel @ e1, rel @ e2])
    near = (np.hypot(uv[:, 0], uv[:, 1]) < radius) & (np.abs(h) < radius) & (normals @ axis < 0)
    return uv[near], h[near], e1, e2


def _neighbourhood_radius(points, centre, spacing) -> float:
    """Three mesh spacings, or more when fewer than 12 vertices lie that close."""
    distance = np.sort(np.linalg.norm(points - centre, axis=1))
    return max(3.0 * spacing, float(distance[min(11, len(distance) - 1)]) * 1.2)


def lowest_point(points: np.ndarray, normals: np.ndarray, spacing: float) -> np.ndarray:
    """The lowest point (along z) of the smooth surface through ``points`` (a condyle's
    vertices, with unit ``normals``, in the tibial frame); the lowest vertex when the
    surface cannot be fitted there (a flat or ragged patch)."""
    down = normals[:, 2] < 0
    candidates = points[down] if np.count_nonzero(down) >= 3 else points
    vertex = candidates[np.argmin(candidates[:, 2])]
    axis = np.array([0, 0, 1.0])
    radius = _neighbourhood_radius(candidates, vertex, spacing)
    centre = vertex.copy()
    for _ in range(4):
        uv, h, e1, e2 = _surface_patch(points, normals, centre, axis, radius)
        coef = _fit(uv, h)
        step = _minimum(coef)
        if step is None:
            return vertex
        moved = centre + step[0] * e1 + step[1] * e2
        if np.linalg.norm(moved[:2] - vertex[:2]) > radius:
            return vertex
        height = _value(coef, step)
        centre = np.array([moved[0], moved[1], centre[2] + float(height)])
        if np.linalg.norm(step) < 1e-4:
            break
    return centre


def _signed(insert: Insert, points, distance, closest, face, exact: bool = True) -> np.ndarray:
    """The distances, negative for points behind the insert's surface: those whose closest
    point is the foot of their perpendicular on a face (inside it) and behind it. A point
    nearest an edge or a corner is outside (beyond an open insert's rim, or over a ridge).
    Not ``exact``: ``closest`` is only near the closest point; behind its face is behind."""
    normal = insert.surface.face_normals(face)
    along = np.einsum("ij,ij->i", np.asarray(points) - closest, normal)
    behind = (along < 0) & (np.abs(along) >= (1 - 1e-6) * distance) if exact else along < 0
    return np.where(behind, -distance, distance)


def closest_to_insert(points, normals, spacing: float, insert: Insert) -> tuple[float, np.ndarray, np.ndarray]:
    """The gap (mm, negative where overlapping) between a condyle (vertices and unit
    normals in the tibial frame) and the insert, and the closest pair of points (on the
    condyle, on the insert)."""
    low = (points[:, 2] < points[:, 2].min() + INSERT_BAND_MM) & (normals[:, 2] < 0.5)
    if not np.any(low):
        low = np.ones(len(points), bool)
    candidates = points[low]
    # each vertex's nearest sample of the insert bounds its distance within the samples' cover;
    # only vertices that can come within PRUNE_MM of the best are measured exactly
    near, sample, owner = insert.surface.nearest_sample(candidates)
    rough = _signed(insert, candidates, near, sample, owner, exact=False)
    keep = rough <= rough.min() + 2 * insert.surface.cover + PRUNE_MM
    candidates, owner = candidates[keep], owner[keep]
    # ranked by the distance to their nearest sample's triangle (an upper bound), the
    # SEEDS best are measured exactly; the fitted surface around the best is searched next
    upper, on_face = insert.surface.distance_to_faces(candidates, owner)
    seeds = candidates[np.argsort(_signed(insert, candidates, upper, on_face, owner))[:SEEDS]]
    distance, on_insert, face = insert.surface.closest(seeds)
    signed = _signed(insert, seeds, distance, on_insert, face)
    best = int(np.argmin(signed))
    vertex, gap, pair = seeds[best], float(signed[best]), on_insert[best]
    normal = insert.surface.face_normals(face[best : best + 1])[0]
    radius = _neighbourhood_radius(candidates, vertex, spacing)
    uv, h, e1, e2 = _surface_patch(points, normals, vertex, normal, radius)  # the condyle over the insert
    coef = _fit(uv, h)
    if coef is None:
        return gap, vertex, pair
    centre, half = np.zeros(2), radius / 2
    grid = np.stack(np.meshgrid(np.linspace(-1, 1, 9), np.linspace(-1, 1, 9)), axis=-1).reshape(-1, 2)
    best_point, best_gap, best_pair = vertex, gap, pair
    for _ in range(3):  # the gap over points of the fitted condyle, each measured exactly to the insert
        at = centre + half * grid
        surface = vertex + at[:, :1] * e1 + at[:, 1:] * e2 + _value(coef, at)[:, None] * normal
        d, q, f = insert.surface.closest(surface)
        d = _signed(insert, surface, d, q, f)
        i = int(np.argmin(d))
        if d[i] < best_gap:
            best_point, best_gap, best_pair = surface[i], float(d[i]), q[i]
        step = _minimum(_fit(at - centre, d))
        if step is None or np.linalg.norm(step) > 2 * half:
            centre, half = at[i], half / 3
            continue
        target = centre + step
        point = vertex + target[0] * e1 + target[1] * e2 + float(_value(coef, target)) * normal
        dt, qt, ft = insert.surface.closest(point[None])
        gt = float(_signed(insert, point[None], dt, qt, ft)[0])
        if gt < best_gap:
            best_point, best_gap, best_pair = point, gt, qt[0]
        centre, half = target, half / 3
    return best_gap, best_point, best_pair


def classify_liftoff(medial: CondyleContact, lateral: CondyleContact, liftoff_mm: float = LIFTOFF_MM) -> str:
    """``none``, ``medial``, ``lateral`` or ``both``: by the gaps when there are some, else by
    the difference of the two condyles' heights."""
    if np.isfinite(medial.gap_mm) and np.isfinite(lateral.gap_mm):
        up = (medial.gap_mm > liftoff_mm, lateral.gap_mm > liftoff_mm)
    else:
        difference = float(medial.lowest[2] - lateral.lowest[2])
        up = (difference > liftoff_mm, -difference > liftoff_mm)
    return {(False, False): "none", (True, False): "medial", (False, True): "lateral", (True, True): "both"}[up]


def condyle_contact(femur: FemoralSurface, femoral_pose, tibial_pose, *, tibial_frame, side: str = "right",
                    insert: Insert | None = None, liftoff_mm: float = LIFTOFF_MM) -> Contact:
    """Both condyles' contact in one frame.

    Parameters
    ----------
    femur : FemoralSurface
        From :func:`prepare_femur`.
    femoral_pose, tibial_pose : array_like of shape (4, 4)
        The components' model → world matrices.
    tibial_frame : array_like of shape (4, 4)
        The tibial anatomical frame (anatomical → model).
    side : {"right", "left"}
        A left knee's points are mirrored (x → −x) and its medial condyle is on the
        subject's right.
    insert : Insert, optional
        From :func:`place_insert`; gives the gaps.
    liftoff_mm : float
        The lift-off threshold.

    Returns
    -------
    Contact
        All NaN when a pose is not finite.
    """
    side = check_side(side)
    F, T, A = (np.asarray(m, dtype=float) for m in (femoral_pose, tibial_pose, tibial_frame))
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(T))):
        return Contact.missing()
    to_tibia = np.linalg.inv(T @ A) @ F
    points = femur.vertices @ to_tibia[:3, :3].T + to_tibia[:3, 3]
    normals = femur.normals @ to_tibia[:3, :3].T
    mirror = np.array([1.0 if side == "right" else -1.0, 1.0, 1.0])
    medial_half = ~femur.right if side == "right" else femur.right
    out = {}
    for name, half in (("medial", medial_half), ("lateral", ~medial_half)):
        if np.count_nonzero(half) < 4:
            raise KinematicsError(f"the femoral component has no {name} condyle on its side of the sagittal plane")
        lowest = lowest_point(points[half], normals[half], femur.spacing) * mirror
        if insert is None:
            out[name] = CondyleContact(lowest)
            continue
        gap, on_femur, on_insert = closest_to_insert(points[half], normals[half], femur.spacing, insert)
        out[name] = CondyleContact(lowest, gap, on_femur * mirror, on_insert * mirror)
    return Contact(out["medial"], out["lateral"], classify_liftoff(out["medial"], out["lateral"], liftoff_mm))


@dataclass(frozen=True)
class Pivot:
    """The pivot of axial rotation on the tray (mirrored frame: +x lateral).

    Attributes
    ----------
    x_mm, y_mm : float
        NaN when not determined.
    kind : str or None
        ``medial``, ``lateral`` or ``central``: the third of the span between the mean
        medial and mean lateral points the pivot lies in (beyond a condyle: that side).
    frames_used, frames_ignored : int
    reason : str
        Why the pivot is not determined, else "".
    """

    x_mm: float
    y_mm: float
    kind: str | None
    frames_used: int
    frames_ignored: int
    reason: str = ""


def pivot(medial_xy, lateral_xy, min_line_mm: float = MIN_LINE_MM, min_spread_deg: float = MIN_SPREAD_DEG) -> Pivot:
    """The least-squares intersection of the lines through each frame's medial and lateral
    points (``(n, 2)`` arrays of x, y; NaN rows are frames without values)."""
    m = np.asarray(medial_xy, dtype=float).reshape(-1, 2)
    lat = np.asarray(lateral_xy, dtype=float).reshape(-1, 2)
    direction = lat - m
    length = np.linalg.norm(direction, axis=1)
    used = np.all(np.isfinite(m), axis=1) & np.all(np.isfinite(lat), axis=1) & (length >= min_line_mm)
    n_used, n_ignored = int(np.count_nonzero(used)), int(len(m) - np.count_nonzero(used))
    if n_used < 2:
        return Pivot(float("nan"), float("nan"), None, n_used, n_ignored,
                     f"{n_used} frame{'' if n_used == 1 else 's'} with both condyles at least "
                     f"{min_line_mm:g} mm apart; two or more are needed")
    d = direction[used] / length[used, None]
    normal = np.column_stack([-d[:, 1], d[:, 0]])
    outer = normal[:, :, None] * normal[:, None, :]
    matrix = outer.sum(axis=0)
    spread = float(np.degrees(np.arcsin(min(1.0, np.sqrt(max(np.linalg.eigvalsh(matrix / n_used)[0], 0.0))))))
    if spread < min_spread_deg:
        return Pivot(float("nan"), float("nan"), None, n_used, n_ignored,
                     f"the medial-lateral lines turn by {spread:.2g} deg (RMS), less than the "
                     f"{min_spread_deg:g} deg that locate a pivot")
    midpoints = 0.5 * (m[used] + lat[used])
    point = np.linalg.solve(matrix, np.einsum("kij,kj->i", outer, midpoints))
    medial_x, lateral_x = float(np.mean(m[used, 0])), float(np.mean(lat[used, 0]))
    share = (point[0] - medial_x) / (lateral_x - medial_x)
    kind = "medial" if share < 1 / 3 else "lateral" if share > 2 / 3 else "central"
    return Pivot(float(point[0]), float(point[1]), kind, n_used, n_ignored)


@dataclass(frozen=True)
class Rollback:
    """A condyle's anterior-posterior position against flexion (mm, degrees); NaN without
    two frames with values."""

    flexion_min_deg: float
    flexion_max_deg: float
    ap_at_min_mm: float
    ap_at_max_mm: float
    excursion_mm: float  # ap at the least flexion minus ap at the greatest: + posterior rollback
    range_mm: float  # greatest minus least ap over the activity


def rollback(flexion_deg, ap_mm) -> Rollback:
    """Femoral rollback of one condyle from its AP positions and the frames' flexion."""
    flexion = np.asarray(flexion_deg, dtype=float)
    ap = np.asarray(ap_mm, dtype=float)
    ok = np.isfinite(flexion) & np.isfinite(ap)
    if np.count_nonzero(ok) < 2:
        return Rollback(*([float("nan")] * 6))
    flexion, ap = flexion[ok], ap[ok]
    low, high = int(np.argmin(flexion)), int(np.argmax(flexion))
    return Rollback(float(flexion[low]), float(flexion[high]), float(ap[low]), float(ap[high]),
                    float(ap[low] - ap[high]), float(ap.max() - ap.min()))
