"""Editing operations on image outlines: pure functions behind the outline tools.

An outline is a (K, 2) float array of ordered pixel points (u, v) = (column, row), origin
at the centre of the top-left pixel; it is closed (periodic) and its last point is NOT a
repeat of the first, so segment i runs from point i to point (i + 1) % K. An edge contour
(from ``fluorogui.core.outlines.edges.edge_contours``) is an open ordered chain of such points.

Every function returns new arrays and never modifies its arguments. An edge mask is a
2-D boolean array indexed [row, column], i.e. [v, u].
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np


# -- helpers ----------------------------------------------------------------------------------
def as_points(points) -> np.ndarray:
    """A float (K, 2) copy of ``points`` (an empty outline gives shape (0, 2))."""
    pts = np.array(points, dtype=float, copy=True)
    if pts.size == 0:
        return np.zeros((0, 2))
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must be a (K, 2) array of (u, v), got shape {pts.shape}")
    return pts


def _point(p) -> np.ndarray:
    p = np.asarray(p, dtype=float).reshape(-1)
    if p.shape != (2,):
        raise ValueError("a point is a pair (u, v)")
    return p


def segment_lengths(points) -> np.ndarray:
    """Lengths (K,) of the closed outline's segments (segment i: point i to point i + 1)."""
    pts = as_points(points)
    if len(pts) < 2:
        return np.zeros(len(pts))
    return np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1)


def outline_spacing(points) -> float:
    """Typical point spacing (px) of a closed outline: the median segment length, which a
    single long gap segment does not disturb."""
    lengths = segment_lengths(points)
    return float(np.median(lengths)) if len(lengths) else 0.0


def _segment_distances(a: np.ndarray, b: np.ndarray, p: np.ndarray):
    """Distance from p to each segment a[i] -> b[i], and the foot parameter in [0, 1]."""
    d = b - a
    dd = np.einsum("ij,ij->i", d, d)
    t = np.where(dd > 0, np.einsum("ij,ij->i", p - a, d) / np.where(dd > 0, dd, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    foot = a + t[:, None] * d
    return np.linalg.norm(p - foot, axis=1), t


def polyline_distance(polyline, p, closed: bool = False) -> float:
    """Distance (px) from p to a polyline (open unless ``closed``); a single point counts."""
    pts = as_points(polyline)
    p = _point(p)
    if len(pts) == 0:
        return float("inf")
    if len(pts) == 1:
        return float(np.linalg.norm(pts[0] - p))
    a, b = (pts, np.roll(pts, -1, axis=0)) if closed else (pts[:-1], pts[1:])
    return float(_segment_distances(a, b, p)[0].min())


# -- single points ------------------------------------------------------------------------------
def nearest_point(points, p) -> tuple[int, float]:
    """Index of the outline point nearest to p and its distance (px)."""
    pts = as_points(points)
    if len(pts) == 0:
        raise ValueError("the outline has no points")
    d = np.linalg.norm(pts - _point(p), axis=1)
    i = int(np.argmin(d))
    return i, float(d[i])


def nearest_segment(points, p) -> tuple[int, float, float]:
    """Segment of the closed outline nearest to p: (i, t, distance), where segment i runs
    from point i to point (i + 1) % K and t in [0, 1] is the foot of p along it."""
    pts = as_points(points)
    if len(pts) < 2:
        raise ValueError("the outline needs at least 2 points to have segments")
    dist, t = _segment_distances(pts, np.roll(pts, -1, axis=0), _point(p))
    i = int(np.argmin(dist))
    return i, float(t[i]), float(dist[i])


def move_point(points, i: int, p) -> np.ndarray:
    """The outline with point i moved to p."""
    pts = as_points(points)
    pts[int(i)] = _point(p)
    return pts


def insert_point(points, p) -> np.ndarray:
    """The outline with p inserted into its nearest segment; the new point's index is
    ``nearest_segment(points, p)[0] + 1`` (an outline of fewer than 2 points gets p appended)."""
    pts = as_points(points)
    p = _point(p)
    if len(pts) < 2:
        return np.vstack([pts, p])
    i = nearest_segment(pts, p)[0]
    return np.insert(pts, i + 1, p, axis=0)


def delete_points(points, indices) -> np.ndarray:
    """The outline without the points at ``indices`` (an int array or a boolean mask)."""
    pts = as_points(points)
    idx = np.asarray(indices)
    if idx.dtype == bool:
        if idx.shape != (len(pts),):
            raise ValueError("a boolean mask must have one entry per point")
        return pts[~idx]
    idx = np.unique(idx.astype(int).reshape(-1))
    if idx.size and (idx[0] < -len(pts) or idx[-1] >= len(pts)):
        raise IndexError("point index out of range")
    return np.delete(pts, idx, axis=0)


# -- regions --------------------------------------------------------------------------------------
def points_in_polygon(points, polygon) -> np.ndarray:
    """Boolean mask (K,) of the points inside a closed polygon (even-odd rule; a lasso).
    A polygon of fewer than 3 vertices contains nothing."""
    pts = as_points(points)
    poly = as_points(polygon)
    inside = np.zeros(len(pts), dtype=bool)
    if len(poly) < 3 or len(pts) == 0:
        return inside
    x, y = pts[:, 0][:, None], pts[:, 1][:, None]
    ax, ay = poly[:, 0][None, :], poly[:, 1][None, :]
    bx, by = np.roll(poly[:, 0], -1)[None, :], np.roll(poly[:, 1], -1)[None, :]
    straddles = (ay > y) != (by > y)
    dy = np.where(by == ay, 1.0, by - ay)
    x_cross = ax + (y - ay) * (bx - ax) / dy
    crossings = straddles & (x < x_cross)
    return (np.count_nonzero(crossings, axis=1) % 2) == 1


def points_near_path(points, path, radius: float) -> np.ndarray:
    """Boolean mask (K,) of the points within ``radius`` px of a brush path (an open
    polyline of N >= 1 centres; one centre is a disc)."""
    pts = as_points(points)
    path = as_points(path)
    near = np.zeros(len(pts), dtype=bool)
    if len(pts) == 0 or len(path) == 0:
        return near
    if len(path) == 1:
        return np.linalg.norm(pts - path[0], axis=1) <= radius
    for a, b in zip(path[:-1], path[1:]):
        near |= _points_to_segment(pts, a, b) <= radius
    return near


def _points_to_segment(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances (K,) from points to the segment a-b."""
    d = b - a
    dd = float(d @ d)
    t = np.zeros(len(pts)) if dd == 0 else np.clip((pts - a) @ d / dd, 0.0, 1.0)
    return np.linalg.norm(pts - (a + t[:, None] * d), axis=1)


def stroke_pixels(shape, path, radius: float) -> np.ndarray:
    """Boolean mask of ``shape`` (rows, columns): the pixels whose centres lie within
    ``radius`` px of a brush path (N >= 1 centres (u, v); one centre is a disc)."""
    mask = np.zeros(tuple(shape), dtype=bool)
    path = as_points(path)
    if len(path) == 0 or radius < 0:
        return mask
    rows, cols = mask.shape
    lo = np.floor(path.min(axis=0) - radius).astype(int)
    hi = np.ceil(path.max(axis=0) + radius).astype(int)
    u0, v0 = max(lo[0], 0), max(lo[1], 0)
    u1, v1 = min(hi[0], cols - 1), min(hi[1], rows - 1)
    if u1 < u0 or v1 < v0:
        return mask
    uu, vv = np.meshgrid(np.arange(u0, u1 + 1, dtype=float), np.arange(v0, v1 + 1, dtype=float))
    grid = np.column_stack([uu.ravel(), vv.ravel()])
    segments = zip(path[:-1], path[1:]) if len(path) > 1 else [(path[0], path[0])]
    hit = np.zeros(len(grid), dtype=bool)
    for a, b in segments:
        hit |= _points_to_segment(grid, a, b) <= radius
    mask[v0:v1 + 1, u0:u1 + 1] = hit.reshape(uu.shape)
    return mask


def erase_in_disc(mask_or_points, centre, radius: float) -> np.ndarray:
    """Erase what lies within ``radius`` px of ``centre``: for a boolean edge mask, a copy
    with the pixels whose centres are in the disc set False; for (K, 2) points, the points
    outside the disc (order kept)."""
    data = np.asarray(mask_or_points)
    centre = _point(centre)
    if data.dtype == bool:
        if data.ndim != 2:
            raise ValueError("an edge mask is a 2-D boolean array")
        return data & ~stroke_pixels(data.shape, centre[None], radius)
    pts = as_points(data)
    return pts[~points_near_path(pts, centre[None], radius)]


def split_at_mask(contour, erased) -> list[np.ndarray]:
    """Pieces of an edge contour whose points do not fall on erased pixels (``erased`` is a
    boolean mask [v, u]; a point belongs to the pixel it rounds to). A contour whose ends
    are neighbours (within 1.5 px) is treated as closed, so its pieces may run across the
    wrap. Pieces of fewer than 2 points are dropped."""
    pts = as_points(contour)
    if len(pts) == 0:
        return []
    erased = np.asarray(erased, dtype=bool)
    rows, cols = erased.shape
    u = np.round(pts[:, 0]).astype(int)
    v = np.round(pts[:, 1]).astype(int)
    inside = (u >= 0) & (u < cols) & (v >= 0) & (v < rows)
    keep = np.ones(len(pts), dtype=bool)
    keep[inside] = ~erased[v[inside], u[inside]]
    if keep.all():
        return [pts]
    padded = np.concatenate([[False], keep, [False]]).astype(np.int8)
    change = np.flatnonzero(np.diff(padded))
    runs = list(zip(change[0::2], change[1::2]))
    closed = len(pts) > 2 and np.linalg.norm(pts[0] - pts[-1]) <= 1.5
    pieces = [pts[s:e] for s, e in runs]
    if closed and len(runs) > 1 and runs[0][0] == 0 and runs[-1][1] == len(pts):
        pieces = [np.vstack([pieces[-1], pieces[0]])] + pieces[1:-1]
    return [p for p in pieces if len(p) >= 2]


# -- contours and gaps ------------------------------------------------------------------------------
def close_gap(points, i: int, j: int, spacing_px: float | None = None) -> np.ndarray:
    """Replace the shorter arc between outline points i and j by a straight run of points.

    The two arcs are i -> j and j -> i in index order (cyclically); the shorter is the
    one with fewer points strictly between i and j (ties: the shorter in length), so
    clicking the two ends of a gap (e.g. the last and first points of an outline taken
    from an open contour) fills the gap, and clicking the two ends of a spurious detour
    cuts it off. The run has points equally spaced at about ``spacing_px`` (default: the
    outline's median spacing) strictly between i and j. Points i and j stay, the kept
    arc keeps its order and the outline keeps its orientation.
    """
    pts = as_points(points)
    k = len(pts)
    i, j = int(i) % max(k, 1), int(j) % max(k, 1)
    if k < 2 or i == j:
        raise ValueError("close_gap needs two different outline points")
    spacing = outline_spacing(pts) if spacing_px is None else float(spacing_px)
    if not spacing > 0:
        raise ValueError("the point spacing must be positive")
    lengths = segment_lengths(pts)

    def arc(a, b):  # interior indices and length of the forward arc a -> b
        idx = (a + 1 + np.arange((b - a - 1) % k)) % k
        seg = (a + np.arange((b - a) % k)) % k
        return idx, float(lengths[seg].sum())

    inner_ij, len_ij = arc(i, j)
    inner_ji, len_ji = arc(j, i)
    if (len(inner_ij), len_ij) <= (len(inner_ji), len_ji):
        start, end, removed = i, j, inner_ij  # the run goes from i to j
    else:
        start, end, removed = j, i, inner_ji
    a, b = pts[start], pts[end]
    n_steps = max(1, int(round(np.linalg.norm(b - a) / spacing)))
    frac = np.arange(1, n_steps)[:, None] / n_steps
    run = a + frac * (b - a)
    keep = np.ones(k, dtype=bool)
    keep[removed] = False
    kept_index = np.flatnonzero(keep)
    at = int(np.flatnonzero(kept_index == start)[0]) + 1
    kept = pts[kept_index]
    return np.vstack([kept[:at], run, kept[at:]])


def join_contours(a, b) -> np.ndarray:
    """Outline ``a`` with contour ``b`` appended after its last point, b reversed if that
    makes the two joins (a's last point to b's first, b's last to a's first, closing the
    outline) shorter in total; so the nearest ends connect."""
    a, b = as_points(a), as_points(b)
    if len(a) == 0:
        return b
    if len(b) == 0:
        return a
    forward = np.linalg.norm(a[-1] - b[0]) + np.linalg.norm(b[-1] - a[0])
    backward = np.linalg.norm(a[-1] - b[-1]) + np.linalg.norm(b[0] - a[0])
    return np.vstack([a, b if forward <= backward else b[::-1]])


def pick_contour(contours: Sequence, p, max_distance_px: float) -> int | None:
    """Index of the contour (an open polyline) nearest to the click p, if it lies within
    ``max_distance_px``; else None."""
    best, best_d = None, float(max_distance_px)
    for index, contour in enumerate(contours):
        pts = as_points(contour)
        if len(pts) == 0:
            continue
        lo, hi = pts.min(axis=0) - best_d, pts.max(axis=0) + best_d
        p2 = _point(p)
        if np.any(p2 < lo) or np.any(p2 > hi):
            continue  # the bounding box is already too far
        d = polyline_distance(pts, p2)
        if d <= best_d and (best is None or d < best_d):
            best, best_d = index, d
    return best
