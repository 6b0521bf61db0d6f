"""Exact outer silhouette of a triangle mesh seen from a point source.

The paper outlines a projected point cloud (``outline.py``), which lies inside the true
silhouette by up to half the point spacing. Here the outline is built from the mesh
itself: silhouette edges (between faces facing towards and away from the source) are
projected, drawn at sub-pixel resolution, the external contour of that drawing is
traced, and every contour point is snapped back onto the nearest projected silhouette
edge. Each outline point therefore carries the model-frame 3D point it images, which
lets the matcher hold correspondences fixed within an evaluation and use analytic
derivatives.

Speed (the matcher draws about a dozen silhouettes per match): a source near one seen
before re-tests only the faces whose plane passed near that one (``_FacingReference``),
and only the edges whose bounding box meets the band around the outer contour are
sampled for snapping. Both give exactly what the plain computation gives
(``tests/core/test_fast_paths.py``).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh

_SHIFT = 4  # fixed-point bits for cv2 drawing
_BAND_PX = 3  # half width (drawing pixels) of the band around the outer contour searched for edges
_BAND_KERNEL = np.ones((2 * _BAND_PX + 1, 2 * _BAND_PX + 1), np.uint8)


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
    """(S, 2) vertex indices of the edges on the silhouette seen from ``source``."""
    s_model = R.T @ (np.asarray(source, dtype=float) - t)
    on = _silhouette_edge_indices(mesh, s_model)
    edges = np.take(mesh.edges, on, axis=0)  # np.take: several times faster than a boolean mask here
    if len(mesh.open_edges):
        return np.vstack([edges, mesh.open_edges])
    return edges


#: a facing reference is made with the faces whose plane passes within this distance (mm)
#: of the source re-tested, and serves sources up to half of it away
FACING_MARGIN_MM = 40.0
#: facing references kept per mesh (the most recently made first)
FACING_REFERENCES = 8


@dataclass(frozen=True)
class _FacingReference:
    """Which faces can change between facing towards and away from sources near ``source``
    (model frame): only those whose plane passes within the margin of it. A face facing
    the source at ``source`` keeps doing so while the source moves less than the distance
    of its plane, so the edges between two faces beyond the margin keep their state."""

    source: np.ndarray  # (3,)
    normals: np.ndarray  # (F, 3) of the faces within the margin
    offsets: np.ndarray  # (F,)
    edges: np.ndarray  # (E,) sorted indices of the edges with a face within the margin
    ends: np.ndarray  # (E, 2) each such edge's faces: index into the facing of those faces, then True, False
    fixed: np.ndarray  # sorted indices of the silhouette edges at ``source`` among the others


def _silhouette_edge_indices(mesh: PreparedMesh, s_model: np.ndarray) -> np.ndarray:
    """Sorted indices into ``mesh.edges`` of the silhouette edges seen from ``s_model``: the
    faces facing it (``n . s > offset``) and the edges between a facing and a turned-away
    face. Sources near one seen before re-test only the faces near grazing there."""
    references = mesh.cache.get("facing", ())
    for ref in references:
        d = s_model - ref.source
        if d @ d <= (0.5 * FACING_MARGIN_MM) ** 2:
            facing = np.empty(len(ref.offsets) + 2, dtype=bool)
            facing[:-2] = ref.normals @ s_model - ref.offsets > 0
            facing[-2:] = True, False
            turning = ref.edges[facing[ref.ends[:, 0]] != facing[ref.ends[:, 1]]]
            return np.sort(np.concatenate([ref.fixed, turning]))  # two disjoint sets
    ef0, ef1 = mesh.edge_faces[:, 0], mesh.edge_faces[:, 1]
    height = mesh.face_normals @ s_model - mesh.face_offsets  # the source's height above each face's plane
    front = height > 0
    on = front[ef0] != front[ef1]
    near = np.abs(height) <= FACING_MARGIN_MM
    faces = np.flatnonzero(near)
    if len(faces) > len(height) // 4:  # a source this close to the mesh: a reference would save little
        return np.flatnonzero(on)
    touched = near[ef0] | near[ef1]
    edges = np.flatnonzero(touched)
    ends = []
    for side in (ef0[edges], ef1[edges]):
        constant = len(faces) + (~front[side]).astype(np.int64)  # True -> len(faces), False -> len(faces) + 1
        ends.append(np.where(near[side], np.searchsorted(faces, side), constant))
    ref = _FacingReference(s_model.copy(), mesh.face_normals[faces], mesh.face_offsets[faces], edges,
                           np.column_stack(ends), np.flatnonzero(on & ~touched))
    mesh.cache["facing"] = (ref,) + tuple(references[: FACING_REFERENCES - 1])  # one assignment: thread-safe
    return np.flatnonzero(on)


def mesh_silhouette(mesh: PreparedMesh, R: np.ndarray, t: np.ndarray, view: View, scale: float = 2.0,
                    spacing_px: float | None = None) -> Silhouette:
    """Outer silhouette outline of ``mesh`` at pose (R, t) in ``view``.

    ``scale`` is the drawing resolution in samples per pixel; it only decides which
    silhouette edges form the outer boundary, the points themselves are exact.
    ``spacing_px`` keeps about one outline point per that many pixels (default: all,
    about ``1 / scale`` px apart), which is what makes it cheap enough for the matcher.
    """
    edges = silhouette_edges(mesh, R, t, view.source)
    if len(edges) == 0:
        raise ValueError("the mesh has no silhouette from this source")
    used = np.zeros(len(mesh.vertices), dtype=bool)
    used[edges.ravel()] = True
    ends = np.flatnonzero(used)  # the vertices on silhouette edges, sorted (np.unique without a sort)
    uv_all, depth_all = view.project_with_depth(mesh.vertices[ends] @ R.T + t)
    if np.any(depth_all <= 1e-6):
        raise ValueError("part of the model lies behind the X-ray source")
    remap = np.empty(mesh.vertices.shape[0], dtype=np.int64)
    remap[ends] = np.arange(len(ends))
    e = remap[edges]
    segs = uv_all[e]  # (S, 2, 2): both ends of every projected edge
    P0, P1 = segs[:, 0], segs[:, 1]

    # draw the projected silhouette edges and trace the outside of the drawing
    u, v = uv_all[:, 0], uv_all[:, 1]  # (per column: much faster than min(0) on an (N, 2) array)
    origin = np.array([u.min(), v.min()]) - 3.0
    size = np.ceil((np.array([u.max(), v.max()]) - origin + 3.0) * scale).astype(int) + 1
    canvas = np.zeros((size[1], size[0]), np.uint8)
    fixed = np.round((segs - origin) * scale * (1 << _SHIFT)).astype(np.int32)
    cv2.polylines(canvas, fixed, False, 255, 1, cv2.LINE_8, _SHIFT)
    contours, _ = cv2.findContours(canvas, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    outer_px = max(contours, key=lambda c: cv2.contourArea(c) + len(c))
    outer = outer_px[:, 0, :].astype(float)
    pts = outer / scale + origin
    if spacing_px:
        pts = pts[:: max(1, int(round(spacing_px * scale)))]

    # snap each contour point onto the nearest projected silhouette edge. Only edges running
    # along the outer contour can be snapped to: keep the samples (every 2 px along each edge)
    # within a band around it (no silhouette edge crosses the outer contour, so an edge on it
    # has samples inside the band); most edges are inner ones
    band = np.zeros_like(canvas)
    band[outer_px[:, 0, 1], outer_px[:, 0, 0]] = 1
    band = cv2.dilate(band, _BAND_KERNEL)
    du, dv = P1[:, 0] - P0[:, 0], P1[:, 1] - P0[:, 1]
    seg_len = np.sqrt(du * du + dv * dv)
    n_sub = np.clip(np.ceil(seg_len / 2.0).astype(int), 1, 400)
    samples, seg_id = _band_samples(P0, P1, n_sub, band, origin, scale, _segments_near_band(segs, band, origin, scale))
    if samples is None:  # (almost) nothing in the band: snap to any edge
        samples, seg_id = _edge_samples(P0, P1, n_sub, np.arange(len(segs)))
    sid, lam_b, p_exact = _snap(pts, samples, seg_id, P0, P1)

    # keep the order, drop repeats of the same exact point
    keep = np.r_[True, np.any(np.abs(np.diff(p_exact, axis=0)) > 1e-9, axis=1)]
    sid, lam_b, p_exact = sid[keep], lam_b[keep], p_exact[keep]

    # 2D edge parameter -> 3D edge parameter (perspective)
    wa, wb = depth_all[e[sid, 0]], depth_all[e[sid, 1]]
    s3 = lam_b * wa / np.maximum(wb - lam_b * (wb - wa), 1e-12)
    va, vb = mesh.vertices[edges[sid, 0]], mesh.vertices[edges[sid, 1]]
    model_pts = va + s3[:, None] * (vb - va)
    return Silhouette(p_exact, model_pts, segs)


def _segments_near_band(segs: np.ndarray, band: np.ndarray, origin: np.ndarray, scale: float) -> np.ndarray:
    """Indices (sorted) of the segments whose bounding box, in drawing cells, holds a band
    cell: the only ones that can have a sample in the band (a superset, never fewer)."""
    a, b = (segs[:, 0] - origin) * scale, (segs[:, 1] - origin) * scale
    lo = np.floor(np.minimum(a, b)).astype(np.int64)  # round() of any point on the segment lies within [lo, hi]
    hi = np.ceil(np.maximum(a, b)).astype(np.int64)
    h, w = band.shape
    c0, r0 = np.clip(lo[:, 0], 0, w), np.clip(lo[:, 1], 0, h)
    c1, r1 = np.clip(hi[:, 0] + 1, 0, w), np.clip(hi[:, 1] + 1, 0, h)
    integral = cv2.integral(band)  # (h + 1, w + 1) sums of band[:r, :c]
    count = integral[r1, c1] - integral[r0, c1] - integral[r1, c0] + integral[r0, c0]
    return np.flatnonzero(count > 0)


def _edge_samples(P0, P1, n_sub, which):
    """Points every <= 2 px along the segments ``which`` (ends included), with their segment."""
    seg_id = np.repeat(which, n_sub[which] + 1)
    frac = _fractions(n_sub[which])
    return P0[seg_id] + frac[:, None] * (P1 - P0)[seg_id], seg_id


def _band_samples(P0, P1, n_sub, band, origin, scale, which):
    """The samples of the segments ``which`` that fall in the band (None if fewer than 8)."""
    samples, seg_id = _edge_samples(P0, P1, n_sub, which)
    cell = np.round((samples - origin) * scale).astype(np.int64)
    on_canvas = (cell[:, 0] >= 0) & (cell[:, 0] < band.shape[1]) & (cell[:, 1] >= 0) & (cell[:, 1] < band.shape[0])
    near = np.zeros(len(samples), dtype=bool)
    near[on_canvas] = band[cell[on_canvas, 1], cell[on_canvas, 0]] > 0
    if near.sum() < 8:
        return None, None
    return samples[near], seg_id[near]


def _snap(pts, samples, seg_id, P0, P1):
    """For every point the nearest point on the segments of its 8 nearest samples: (segment,
    parameter along it, the point)."""
    _, nearest = cKDTree(samples).query(pts, k=min(8, len(samples)))
    nearest = np.atleast_2d(nearest)
    cand = seg_id[nearest]  # (K, k)
    ax, ay = P0[cand, 0], P0[cand, 1]
    abx, aby = P1[cand, 0] - ax, P1[cand, 1] - ay
    px, py = pts[:, 0:1], pts[:, 1:2]
    lam = ((px - ax) * abx + (py - ay) * aby) / np.maximum(abx * abx + aby * aby, 1e-12)
    np.clip(lam, 0.0, 1.0, out=lam)
    qx, qy = ax + lam * abx, ay + lam * aby
    dx, dy = qx - px, qy - py
    best = np.argmin(np.sqrt(dx * dx + dy * dy), axis=1)
    rows = np.arange(len(pts))
    return cand[rows, best], lam[rows, best], np.column_stack([qx[rows, best], qy[rows, best]])


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


def _fractions(n_sub: np.ndarray) -> np.ndarray:
    """Concatenated linspace(0, 1, k + 1) for every k in n_sub, vectorised."""
    total = n_sub + 1
    starts = np.r_[0, np.cumsum(total)[:-1]]
    idx = np.arange(total.sum()) - np.repeat(starts, total)
    return idx / np.repeat(n_sub, total)
