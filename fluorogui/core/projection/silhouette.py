"""Exact outer silhouette of a triangle mesh seen from a point source.

The paper outlines a projected point cloud (``outline.py``), which lies inside the true
silhouette by up to half the point spacing. Here the outline is built from the mesh
itself: silhouette edges (between faces facing towards and away from the source) are
projected, drawn at sub-pixel resolution, the external contour of that drawing is
traced, and every contour point is snapped back onto the nearest projected silhouette
edge. Each outline point therefore carries the model-frame 3D point it images, which
lets the matcher hold correspondences fixed within an evaluation and use analytic
derivatives.

Speed (the matcher draws a silhouette per view and evaluation): the silhouette edges are
kept between calls and updated only where a face can have turned (``core.projection.facing``);
the drawing keeps, per cell, a segment drawn through it, so a contour cell is snapped
onto the nearest segment drawn around it without searching all edges (only the filled
cells of the 5 x 5 square around it are measured; ``tests/core/test_silhouette_exact.py``
holds the whole pipeline to its plain version bit for bit). Against an
independent outline (the filled triangles' contour at 16 cells per px) the points lie as
close as the earlier band-and-KD-tree snapping's (mean 0.031 px, 99 % within 0.08 px)
at half the cost.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fluorogui.core.projection.facing import facing_edges
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh


@dataclass
class Silhouette:
    """Ordered outer outline of a projected mesh."""

    points_px: np.ndarray  # (K, 2) ordered along the outline, closed implicitly
    model_points: np.ndarray  # (K, 3) model-frame points that project onto points_px
    segments_px: np.ndarray  # (S, 2, 2) all projected silhouette edges (for drawing)

    @property
    def arc_length(self) -> np.ndarray:
        p = self.points_px
        du, dv = np.roll(p[:, 0], -1) - p[:, 0], np.roll(p[:, 1], -1) - p[:, 1]
        return np.r_[0.0, np.cumsum(np.sqrt(du * du + dv * dv))]

    def resample(self, n: int | None = None, spacing_px: float | None = None) -> "Silhouette":
        """About equally spaced outline points (exact ones: chosen, not interpolated)."""
        s = self.arc_length
        total = s[-1]
        if n is None:
            n = max(8, int(round(total / max(spacing_px or 1.0, 1e-6))))
        n = min(n, len(self.points_px))
        targets = (np.arange(n) + 0.5) * total / n
        idx = np.clip(np.searchsorted(s[:-1], targets), 0, len(self.points_px) - 1)
        idx = np.unique(idx)
        return Silhouette(self.points_px[idx], self.model_points[idx], self.segments_px)


def silhouette_edges(mesh: PreparedMesh, R: np.ndarray, t: np.ndarray, source: np.ndarray) -> np.ndarray:
    """(S, 2) vertex indices of the edges on the silhouette seen from ``source`` (read-only:
    kept for the calls that see the same edges)."""
    return facing_edges(mesh, R.T @ (np.asarray(source, dtype=float) - t)).edges


def mesh_silhouette(mesh: PreparedMesh, R: np.ndarray, t: np.ndarray, view: View, *, scale: float = 2.0,
                    spacing_px: float | None = None) -> Silhouette:
    """Outer silhouette outline of ``mesh`` at pose (R, t) in ``view``.

    ``scale`` is the drawing resolution in samples per pixel; it only decides which
    silhouette edges form the outer boundary, the points themselves are exact.
    ``spacing_px`` keeps about one outline point per that many pixels (default: all,
    about ``1 / scale`` px apart), which is what makes it cheap enough for the matcher.
    """
    found = facing_edges(mesh, R.T @ (np.asarray(view.source, dtype=float) - t))
    edges, e = found.edges, found.local  # e: the edges' ends as indices into found.ends
    if len(edges) == 0:
        raise ValueError("the mesh has no silhouette from this source")
    uv_all, depth_all = view.project_with_depth(mesh.vertices[found.ends] @ R.T + t)
    if np.any(depth_all <= 1e-6):
        raise ValueError("part of the model lies behind the X-ray source")
    segs = uv_all[e]  # (S, 2, 2): both ends of every projected edge
    P0, P1 = segs[:, 0], segs[:, 1]

    # draw the projected silhouette edges (each cell remembers a segment through it), trace
    # the outside of the drawing, and snap every contour cell onto the nearest of the
    # segments drawn in the cells around it
    u, v = uv_all[:, 0], uv_all[:, 1]  # (per column: much faster than min(0) on an (N, 2) array)
    origin = np.array([u.min(), v.min()]) - 3.0
    size = np.ceil((np.array([u.max(), v.max()]) - origin + 3.0) * scale).astype(int) + 1
    drawn = _segment_cells(((uv_all - origin) * scale)[e], (size[1], size[0]))  # (each end scaled once)
    filled = (drawn >= 0).view(np.uint8)  # (a bool is a byte of 0 or 1: no copy)
    contours, _ = cv2.findContours(filled, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    cells = max(contours, key=lambda c: cv2.contourArea(c) + len(c))[:, 0, :]
    if spacing_px:
        cells = cells[:: max(1, int(round(spacing_px * scale)))]
    sid, lam_b, p_exact = _snap(cells / scale + origin, _nearby_segments(drawn, cells), P0, P1)

    # keep the order, drop repeats of the same exact point
    keep = np.empty(len(p_exact), bool)
    keep[0] = True
    keep[1:] = (np.abs(np.diff(p_exact[:, 0])) > 1e-9) | (np.abs(np.diff(p_exact[:, 1])) > 1e-9)
    sid, lam_b, p_exact = sid[keep], lam_b[keep], p_exact[keep]

    # 2D edge parameter -> 3D edge parameter (perspective)
    wa, wb = depth_all[e[sid, 0]], depth_all[e[sid, 1]]
    s3 = lam_b * wa / np.maximum(wb - lam_b * (wb - wa), 1e-12)
    va, vb = mesh.vertices[edges[sid, 0]], mesh.vertices[edges[sid, 1]]
    model_pts = va + s3[:, None] * (vb - va)
    return Silhouette(p_exact, model_pts, segs)


def _segment_cells(segments: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Drawing (``shape``; -1 where empty) of segments given in drawing cells: every cell a
    segment passes through holds a segment's index (the last drawn where several cross).
    Each segment is sampled at steps under one cell, so its cells are 8-connected and
    closed loops of edges draw closed curves. The segments must lie inside the drawing.
    (Per coordinate and into the flat drawing: the same numbers as on (N, 2) arrays, at
    half the cost.)"""
    x0, y0 = segments[:, 0, 0], segments[:, 0, 1]
    dx, dy = segments[:, 1, 0] - x0, segments[:, 1, 1] - y0
    # (the cells' coordinates are not negative, so the cast's truncation is np.floor)
    n = np.maximum(np.abs(dx), np.abs(dy)).astype(np.int64) + 2  # samples per segment
    seg = np.repeat(np.arange(len(segments), dtype=np.int32), n)
    k = np.arange(len(seg)) - np.repeat(np.cumsum(n) - n, n)
    frac = k / np.repeat(n - 1, n)
    col = (np.repeat(x0, n) + frac * np.repeat(dx, n) + 0.5).astype(np.int64)
    cell = (np.repeat(y0, n) + frac * np.repeat(dy, n) + 0.5).astype(np.int64)  # the row, then the flat index
    cell *= shape[1]
    cell += col
    drawn = np.full(shape, -1, np.int32)
    drawn.ravel()[cell] = seg
    return drawn


#: half width (cells) of the square around a contour cell whose segments are snapped to
_NEARBY_CELLS = 2


def _nearby_segments(drawn: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(K, 25) the segments drawn in the 5 x 5 cells around each contour cell (-1: none), in
    row-major order of the square. The cell itself holds one, so every row has at least one.
    Squares reaching past the drawing's border repeat its last row or column."""
    h, w = drawn.shape
    rows, cols = cells[:, 1], cells[:, 0]
    k = _NEARBY_CELLS
    off = np.arange(-k, k + 1)
    if rows.min() >= k and cols.min() >= k and rows.max() < h - k and cols.max() < w - k:
        # every square inside the drawing (as the margin around the outline makes it): one
        # gather from the flat drawing
        return drawn.ravel()[(rows * w + cols)[:, None] + (off[:, None] * w + off).ravel()]
    dr, dc = (g.ravel() for g in np.meshgrid(off, off, indexing="ij"))
    rows = np.minimum(np.maximum(rows[:, None] + dr, 0), h - 1)  # (np.clip's wrapper: slower)
    cols = np.minimum(np.maximum(cols[:, None] + dc, 0), w - 1)
    return drawn[rows, cols]


def _snap(pts, cand, P0, P1):
    """For every point the nearest point on its candidate segments (``cand``, -1 for none):
    (segment, parameter along it, the point). Of equally near candidates the first in its
    row. Only the filled candidates are measured (about a fifth of a 5 x 5 square); the
    segments' numbers are gathered in one step from a table of them, and each row's nearest
    is found over its own candidates (``reduceat``), not over a padded square."""
    table = np.empty((5, len(P0)))  # per segment: a, b - a, |b - a|^2 (at least 1e-12)
    ax, ay, abx, aby, length2 = table
    ax[:], ay[:] = P0[:, 0], P0[:, 1]
    np.subtract(P1[:, 0], ax, out=abx)
    np.subtract(P1[:, 1], ay, out=aby)
    np.maximum(abx * abx + aby * aby, 1e-12, out=length2)
    width = cand.shape[1]
    flat = cand.ravel()
    at = np.flatnonzero(flat >= 0)  # the filled candidates, row by row
    starts = np.searchsorted(at, np.arange(len(pts)) * width)  # each row's first
    if len(pts) and np.diff(np.append(starts, len(at))).min() == 0:
        raise ValueError("a point without a candidate segment")  # (the contour cell itself holds one)
    s = flat[at]
    row = at // width
    px, py = pts[:, 0][row], pts[:, 1][row]
    sax, say, sabx, saby, slength2 = np.take(table, s, axis=1)
    lam = ((px - sax) * sabx + (py - say) * saby) / slength2
    np.maximum(lam, 0.0, out=lam)
    np.minimum(lam, 1.0, out=lam)
    qx, qy = sax + lam * sabx, say + lam * saby
    dx, dy = qx - px, qy - py
    d2 = dx * dx + dy * dy
    if not len(pts):
        return s, lam, np.column_stack([qx, qy])
    nearest = np.minimum.reduceat(d2, starts)
    # the first candidate of its row at the row's nearest distance (np.argmin's choice)
    best = np.minimum.reduceat(np.where(d2 == nearest[row], np.arange(len(at)), len(at)), starts)
    if best.max() >= len(at):  # a NaN distance (no nearest equals itself): argmin's choice, the first NaN
        d2_square = np.full(flat.shape, np.inf)
        d2_square[at] = d2
        where = np.full(flat.shape, -1)
        where[at] = np.arange(len(at))
        best = where[np.arange(len(pts)) * width + np.argmin(d2_square.reshape(cand.shape), axis=1)]
    return s[best], lam[best], np.column_stack([qx[best], qy[best]])


def projected_region(view: View, placed, margin_px: int = 3) -> np.ndarray:
    """Boolean image of where meshes placed at ``(mesh, R, t)`` project in ``view`` (their
    filled outer silhouettes), grown by ``margin_px``: another component's area, which
    segmentation and matching leave out. A mesh partly behind the source is left out. (Drawn
    and grown in the box around the outlines only: the same pixels, a fraction of the work.)"""
    w, h = view.image_size
    mask = np.zeros((h, w), bool)
    outlines = []
    for mesh, R, t in placed:
        try:
            outlines.append(mesh_silhouette(mesh, R, t, view, spacing_px=1.0).points_px)
        except ValueError:
            continue
    if not outlines:
        return mask
    every = np.vstack(outlines)
    reach = max(int(margin_px), 0) + 2
    u0, v0 = (max(int(np.floor(every[:, k].min())) - reach, 0) for k in (0, 1))
    u1, v1 = min(int(np.ceil(every[:, 0].max())) + reach + 1, w), min(int(np.ceil(every[:, 1].max())) + reach + 1, h)
    if u1 <= u0 or v1 <= v0:
        return mask  # wholly beyond the image
    box = np.zeros((v1 - v0, u1 - u0), np.uint8)
    offset = np.array([u0, v0]) * 16
    for outline in outlines:
        cv2.fillPoly(box, [np.round(outline * 16).astype(np.int32) - offset], 1, cv2.LINE_8, 4)
    if margin_px > 0 and box.any():
        box = cv2.dilate(box, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1,) * 2))
    mask[v0:v1, u0:u1] = box > 0
    return mask
