"""Automatic initial pose: find a component in both images with no pose to start from.

``find_components`` / ``Placement`` (``find.py``, importable from here too) is the entry
point for "find implants": edge-based, ~1 s per frame, and it says when it is not sure.
The blob-mask search below is the earlier method, kept for its existing callers; on the
real biplane data its masks lose the tibial tray and merge with soft tissue. This module
also holds the field-of-view mask and the orientation grid that ``find`` uses.

Steps of the blob-mask search (all pure numpy / OpenCV):

1. ``dark_blobs``: metal components are the darkest regions inside the bright field of
   view. The black frame around the intensifier disc is removed first (dark pixels
   connected to the image edges; the disc is then its convex hull, shrunk by a margin),
   then a two-level Otsu split (Otsu inside the field of view separates the bright
   background from everything darker; a second Otsu on the darker part separates metal
   from soft tissue and bone), a morphological clean-up, connected components above a
   minimum area, holes filled (the outline is the outer boundary).
2. ``search_pose``: a coarse global search over orientations for one component given its
   blob mask in each view. Orientations come from a super-Fibonacci spiral (Alexa 2022),
   an even spread over SO(3). For each, the model centroid is put on the point where the
   rays through the two mask centroids meet (``triangulate``), the silhouette is drawn
   at reduced resolution (silhouette edges of the mesh, outer contour filled), shifted in
   each view so its centroid meets the mask centroid, and scored by the mean IoU with the
   masks. The best few are improved by a local hill climb over small rotations (which
   also corrects the translation so both silhouette centroids meet the mask centroids in
   3D), then refined with the fast matcher on the mask outlines; the lowest objective
   wins.
3. ``assign_blobs``: which blob in each view is which component. Blob pairs whose centroid
   rays nearly meet are candidates; each component is searched on the plausible pairs
   (largest blobs first) and the assignment with the best total score, without using a
   blob twice, is kept.

Mask outlines are pixel-centre boundaries, which lie ~0.5 px inside the true edge; they
are pushed out by half a pixel along the outward normal before matching.
"""
from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field
from typing import Callable, NamedTuple, Sequence

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from .edges import outline_from_mask
from .geometry import View, triangulate
from .matching import MatchProblem, MatchResult, MatchSettings, match
from .mesh import PreparedMesh
from .pose import angles_from_matrix, rotation_matrix, rotvec_matrix
from .silhouette import mesh_silhouette, silhouette_edges
from .spline import OutlineSpline

ProgressCallback = Callable[[int, int], None]


class SearchCancelled(Exception):
    """The caller's cancel flag was set during a pose search."""


class Blob(NamedTuple):
    """A dark region: boolean mask (H, W), area (pixels) and centroid (u, v) in pixels."""

    mask: np.ndarray
    area: int
    centroid: np.ndarray


# -- segmentation --------------------------------------------------------------------------
def field_of_view(image: np.ndarray, border_level: float | None = None, margin_px: int = 12) -> np.ndarray:
    """Boolean mask of the intensifier's field of view (the bright disc), shrunk by ``margin_px``.

    The black frame is what is darker than ``border_level`` and connected to the image
    edges; the field of view is the convex hull of the rest (the disc is convex, so
    components touching its rim are not cut off). The default level is a quarter of the
    way from the frame's grey (the median of a strip along the image border) up to the
    darkest grey in the middle of the image (its 0.5th percentile), at least 4: a frame
    that is not quite black (noise, an offset) is still found."""
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), 1.5)
    h, w = img.shape
    if border_level is None:
        centre = float(np.percentile(img[h // 4: 3 * h // 4, w // 4: 3 * w // 4], 0.5))
        k = max(2, min(h, w) // 50)
        frame = float(np.median(np.r_[img[:k].ravel(), img[-k:].ravel(), img[:, :k].ravel(), img[:, -k:].ravel()]))
        frame = min(frame, centre)  # no darker frame: the field of view fills the image
        border_level = max(4.0, frame + 0.25 * (centre - frame))
    dark = (img <= border_level).astype(np.uint8)
    n, labels = cv2.connectedComponents(dark, connectivity=8)
    edge_labels = np.unique(np.r_[labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    edge_labels = edge_labels[edge_labels > 0]
    outside = np.isin(labels, edge_labels) if len(edge_labels) else np.zeros_like(dark, bool)
    inside = (~outside).astype(np.uint8)
    inside = cv2.morphologyEx(inside, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
    contours, _ = cv2.findContours(inside, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return np.zeros((h, w), bool)
    hull = cv2.convexHull(np.vstack(contours))  # the hull of the outer boundaries is that of every pixel
    fov = np.zeros((h, w), np.uint8)
    cv2.fillConvexPoly(fov, hull, 1)
    if margin_px > 0:
        fov = cv2.erode(fov, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1,) * 2))
    return fov > 0


def metal_threshold(image: np.ndarray, fov: np.ndarray) -> float:
    """Grey level separating metal from the rest inside the field of view (two-level Otsu)."""
    values = np.asarray(image)[fov].astype(np.uint8).reshape(-1, 1)
    if values.size == 0:
        return 0.0
    level, _ = cv2.threshold(values, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    darker = values[values <= level]
    if darker.size < 16:
        return float(level)
    level2, _ = cv2.threshold(darker.reshape(-1, 1), 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    return float(level2)


def dark_blobs(image: np.ndarray, min_area: int = 1500, max_blobs: int = 6, margin_px: int = 30,
               threshold: float | None = None, fov: np.ndarray | None = None, level_step: int = 2,
               min_edge: float = 0.0, edge_quantile: float = 0.25,
               max_rim_fraction: float = 0.3) -> list[Blob]:
    """Implant candidates: dark regions inside the field of view with sharp edges, best first.

    Metal is the darkest thing in the image, but its grey level shifts with the tissue
    around it and the intensifier's response, and thick soft tissue can be as dark as a
    thin part of a component. A global threshold therefore does not separate them here.
    Instead every grey level from the darkest percentile up to the field of view's Otsu
    level is tried (``level_step`` apart); each connected dark region at each level is
    scored by a low quantile (``edge_quantile``) of the gradient magnitude along its boundary (a metal edge is a sharp
    step, soft-tissue edges are gradual, and a level above the metal spills into tissue
    and loses edge strength), ignoring boundary on the rim of the field of view. The
    best-scoring regions that do not overlap are kept, sorted by that score (the score
    is returned in the order; ``area`` and ``centroid`` are the region's).

    ``threshold`` forces one grey level (plain thresholding); ``fov`` overrides the
    automatic field of view (``field_of_view(image, margin_px=margin_px)``)."""
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.dtype != np.uint8:  # 16-bit or float: stretch to 8 bit
        f = img.astype(np.float64)
        lo, hi = np.percentile(f, [0.1, 99.9])
        img = np.clip((f - lo) / max(hi - lo, 1e-12) * 255, 0, 255).astype(np.uint8)
    if fov is None:
        fov = field_of_view(img, margin_px=margin_px)
    fov = np.asarray(fov, bool)
    if not fov.any():
        return []
    smooth = cv2.GaussianBlur(img, (0, 0), 1.0)
    g = cv2.GaussianBlur(img.astype(np.float32), (0, 0), 1.5)
    grad = np.hypot(cv2.Sobel(g, cv2.CV_32F, 1, 0), cv2.Sobel(g, cv2.CV_32F, 0, 1)) / 8.0
    inner = cv2.erode(fov.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    values = smooth[fov]
    if threshold is not None:
        levels = [int(round(threshold))]
    else:
        otsu, _ = cv2.threshold(values.reshape(-1, 1), 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        lo = int(np.percentile(values, 0.2)) + 2
        levels = list(range(lo, max(lo + 1, int(otsu)), max(1, level_step)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
    found = []  # (score, area, level, label image, label)
    for level in levels:
        dark = ((smooth <= level) & fov).astype(np.uint8)
        dark = cv2.morphologyEx(dark, cv2.MORPH_OPEN, kernel)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(dark, connectivity=8)
        big = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] >= min_area)
        big = big[big > 0]
        if len(big) == 0:
            continue
        edge = dark > cv2.erode(dark, np.ones((3, 3), np.uint8))
        boundary = edge & inner
        rim = np.bincount(labels[edge & ~inner], minlength=n)
        lab = labels[boundary]
        gb = grad[boundary]
        order = np.lexsort((gb, lab))
        lab, gb = lab[order], gb[order]
        count = np.bincount(lab, minlength=n)
        first = np.r_[0, np.cumsum(count)[:-1]]
        for k in big:
            if count[k] < 50 or rim[k] > max_rim_fraction * (rim[k] + count[k]):
                continue  # mostly the dark ramp at the rim of the field of view
            # a low quantile: a region is only as good as the weakest quarter of its edge
            score = float(gb[first[k] + int(edge_quantile * (count[k] - 1))])
            found.append((score, int(stats[k, cv2.CC_STAT_AREA]), level, labels, int(k)))
    found.sort(key=lambda f: -f[0])
    taken = np.zeros(img.shape, bool)
    blobs = []
    for score, area, level, labels, k in found:
        if score < min_edge or len(blobs) >= max_blobs:
            break
        region = labels == k
        if np.count_nonzero(region & taken) > 0.02 * area:
            continue
        region = cv2.morphologyEx(region.astype(np.uint8), cv2.MORPH_CLOSE, kernel)
        contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        filled = np.zeros_like(region)
        cv2.drawContours(filled, contours, -1, 1, cv2.FILLED)  # fill holes
        filled = filled > 0
        taken |= cv2.dilate(filled.astype(np.uint8), kernel) > 0
        m = cv2.moments(filled.astype(np.uint8), binaryImage=True)
        blobs.append(Blob(filled, int(m["m00"]), np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])))
    return blobs


def mask_outline(mask: np.ndarray, offset_px: float = 0.5, step: int = 1) -> np.ndarray:
    """Ordered outer boundary of a mask, pushed out by ``offset_px`` from the boundary
    pixel centres to the pixel edges (where a thresholded edge lies)."""
    pts = outline_from_mask(mask)
    pts = _smooth_closed(pts, 2)[::max(1, step)]
    if offset_px:
        t = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
        n = np.column_stack([t[:, 1], -t[:, 0]])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        x, y = pts[:, 0], pts[:, 1]
        area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
        if area < 0:
            n = -n
        # n now points to the right of the direction of travel in a y-down frame for a
        # positively oriented polygon, i.e. outwards; check with the centroid to be sure
        c = pts.mean(0)
        if np.mean(np.einsum("ij,ij->i", pts - c, n)) < 0:
            n = -n
        pts = pts + offset_px * n
    return pts


def _smooth_closed(p: np.ndarray, k: int) -> np.ndarray:
    """Moving average over 2k+1 points of a closed polyline (removes the pixel staircase)."""
    if k <= 0 or len(p) < 4 * k + 2:
        return p
    acc = np.zeros_like(p, dtype=float)
    for s in range(-k, k + 1):
        acc += np.roll(p, s, axis=0)
    return acc / (2 * k + 1)


# -- orientations --------------------------------------------------------------------------
def orientation_grid(n: int) -> np.ndarray:
    """(n, 3, 3) rotations spread evenly over SO(3) (super-Fibonacci spiral, Alexa 2022)."""
    phi = np.sqrt(2.0)
    psi = 1.533751168755204288118041
    s = np.arange(n) + 0.5
    r = np.sqrt(s / n)
    big = np.sqrt(1.0 - s / n)
    a = 2 * np.pi * s / phi
    b = 2 * np.pi * s / psi
    q = np.column_stack([r * np.sin(a), r * np.cos(a), big * np.sin(b), big * np.cos(b)])  # (x, y, z, w)
    return Rotation.from_quat(q).as_matrix()


# -- fast low-resolution silhouettes -------------------------------------------------------------
def silhouette_mask(mesh: PreparedMesh, R: np.ndarray, t: np.ndarray, view: View, scale: float = 0.25,
                    shape: tuple[int, int] | None = None) -> np.ndarray:
    """Filled outer silhouette of ``mesh`` at (R, t) in ``view``, drawn at ``scale`` of the
    image resolution (uint8 0/1, shape (H*scale, W*scale) unless ``shape`` is given)."""
    if shape is None:
        w, h = view.image_size
        shape = (int(round(h * scale)), int(round(w * scale)))
    edges = silhouette_edges(mesh, R, t, view.source)
    canvas = np.zeros(shape, np.uint8)
    if len(edges) == 0:
        return canvas
    ends, inv = np.unique(edges, return_inverse=True)
    X = mesh.vertices[ends] @ R.T + t
    if np.any((X - view.source) @ view.normal <= 1e-6):
        return canvas
    uv = view.project(X) * scale + (scale - 1.0) / 2.0  # pixel centres of the small grid
    segs = uv[inv.reshape(-1, 2)]
    fixed = np.round(segs * 16).astype(np.int32)
    cv2.polylines(canvas, list(fixed), False, 1, 1, cv2.LINE_8, 4)
    contours, _ = cv2.findContours(canvas, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(canvas, contours, -1, 1, cv2.FILLED)
    return canvas


def _moments(m: np.ndarray) -> tuple[float, np.ndarray]:
    mo = cv2.moments(m, binaryImage=True)
    if mo["m00"] <= 0:
        return 0.0, np.array([np.nan, np.nan])
    return mo["m00"], np.array([mo["m10"] / mo["m00"], mo["m01"] / mo["m00"]])


def _shift(m: np.ndarray, d: np.ndarray) -> np.ndarray:
    M = np.array([[1.0, 0.0, d[0]], [0.0, 1.0, d[1]]])
    return cv2.warpAffine(m, M, (m.shape[1], m.shape[0]), flags=cv2.INTER_NEAREST)


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    inter = np.count_nonzero(a & b)
    union = np.count_nonzero(a | b)
    return inter / union if union else 0.0


def mask_iou(mesh: PreparedMesh, pose, views: Sequence[View], masks: Sequence[np.ndarray],
             scale: float = 1.0) -> list[float]:
    """Silhouette IoU of ``mesh`` at ``pose`` (mm, deg) with the mask in every view."""
    pose = np.asarray(pose, dtype=float)
    R = rotation_matrix(*pose[3:])
    out = []
    for view, mask in zip(views, masks):
        target = np.asarray(mask, np.uint8)
        if scale != 1.0:
            target = cv2.resize(target, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        sil = mesh_silhouette(mesh, R, pose[:3], view)
        drawn = np.zeros(target.shape, np.uint8)
        cv2.fillPoly(drawn, [np.round((sil.points_px * scale + (scale - 1) / 2) * 16).astype(np.int32)], 1,
                     cv2.LINE_8, 4)
        out.append(_iou(drawn > 0, target > 0))
    return out


# -- the search ---------------------------------------------------------------------------------
@dataclass
class SearchResult:
    pose: np.ndarray  # mm, degrees
    objective_mm: float  # matcher objective on the mask outlines
    iou: list[float]  # silhouette IoU with the masks, per view (full resolution)
    coarse_iou: float  # best mean IoU of the orientation scan
    match: MatchResult | None = None
    seconds: float = 0.0
    candidates: list = field(default_factory=list)  # (coarse IoU, pose) of the refined candidates

    @property
    def mean_iou(self) -> float:
        return float(np.mean(self.iou))


class _Scorer:
    """Mean silhouette IoU with the masks at reduced resolution, centroids aligned per view."""

    def __init__(self, mesh, views, masks, scale):
        self.mesh, self.views, self.scale = mesh, list(views), scale
        self.small = []
        for m in masks:
            w, h = m.shape[1], m.shape[0]
            s = cv2.resize(np.asarray(m, np.uint8), (int(round(w * scale)), int(round(h * scale))),
                           interpolation=cv2.INTER_AREA)
            self.small.append(s > 0)
        self.small_u8 = [s.astype(np.uint8) for s in self.small]
        self.centroids = [_moments(s)[1] for s in self.small_u8]
        self.calls = 0

    def score(self, R, c) -> tuple[float, list[np.ndarray]]:
        """IoU and, per view, the silhouette-centroid shift (small pixels) still needed."""
        self.calls += 1
        t = c - R @ self.mesh.centroid
        ious, shifts = [], []
        for view, target, tc in zip(self.views, self.small, self.centroids):
            m = silhouette_mask(self.mesh, R, t, view, self.scale, target.shape)
            area, mc = _moments(m)
            if area == 0:
                return 0.0, [np.zeros(2)] * len(self.views)
            d = tc - mc
            ious.append(_iou(_shift(m, d) > 0, target))
            shifts.append(d)
        return float(np.mean(ious)), shifts

    def recentre(self, R, c, iterations: int = 2) -> np.ndarray:
        """Move the centroid so the silhouette centroids meet the mask centroids (3D, least squares)."""
        for _ in range(iterations):
            _, shifts = self.score(R, c)
            A, b = [], []
            for view, d in zip(self.views, shifts):
                _, J = view.project_jacobian(c[None, :])
                A.append(J[0])
                b.append(d / self.scale)
            delta = np.linalg.lstsq(np.vstack(A), np.concatenate(b), rcond=None)[0]
            c = c + delta
            if np.linalg.norm(delta) < 0.2:
                break
        return c


def _check(cancel):
    if cancel is not None and cancel():
        raise SearchCancelled


def search_component(mesh: PreparedMesh, views: Sequence[View], masks: Sequence[np.ndarray],
                     n_orientations: int = 800, keep: int = 6, refine: int = 3, scale: float = 0.25,
                     settings: MatchSettings | None = None, progress: ProgressCallback | None = None,
                     cancel: Callable[[], bool] | None = None) -> SearchResult:
    """Global pose search of one component from its blob mask in each of two views.

    ``n_orientations`` evenly spread orientations are scored; the best ``keep`` are hill
    climbed (rotation steps 8, 4, 2 degrees, translation re-centred in 3D) and the best
    ``refine`` of those are matched on the mask outlines. Raises ``SearchCancelled`` when
    ``cancel()`` becomes true."""
    t0 = time.perf_counter()
    if len(views) != 2 or len(masks) != 2:
        raise ValueError("the pose search needs a mask in each of two views")
    masks = [np.asarray(m).astype(bool) for m in masks]
    if any(not m.any() for m in masks):
        raise ValueError("a mask is empty")
    scorer = _Scorer(mesh, views, masks, scale)
    centroids = [_moments(m.astype(np.uint8))[1] for m in masks]
    centre, _ = triangulate(views, centroids)

    rotations = orientation_grid(n_orientations)
    total = n_orientations + keep * 30 + refine
    scores = np.zeros(len(rotations))
    for k, R in enumerate(rotations):
        if k % 25 == 0:
            _check(cancel)
            if progress is not None:
                progress(k, total)
        scores[k] = scorer.score(R, centre)[0]

    # local hill climb of the best few: small rotations about the model centroid
    axes = np.vstack([np.eye(3), -np.eye(3)])
    refined = []
    done = n_orientations
    for k in np.argsort(-scores)[:keep]:
        _check(cancel)
        R = rotations[k]
        c = scorer.recentre(R, centre.copy())
        best, _ = scorer.score(R, c)
        for step in (8.0, 4.0, 2.0):
            for _ in range(4):  # a few rounds per step size (bounded: the score is noisy)
                improved = False
                for ax in axes:
                    Rn = rotvec_matrix(np.radians(step) * ax) @ R
                    s, _ = scorer.score(Rn, c)
                    if s > best + 1e-4:
                        best, R, improved = s, Rn, True
                if not improved:
                    break
            c2 = scorer.recentre(R, c, 1)
            s2, _ = scorer.score(R, c2)
            if s2 >= best - 0.01:
                c, best = c2, s2
        refined.append((best, R, c))
        done += 30
        if progress is not None:
            progress(min(done, total - refine), total)
    refined.sort(key=lambda r: -r[0])

    # refine with the matcher on the mask outlines
    splines = [OutlineSpline.fit(mask_outline(m, step=2)) for m in masks]
    problem = MatchProblem(mesh, views, splines)
    settings = settings or MatchSettings(method="fast", huber_px=3.0)
    best_res: MatchResult | None = None
    candidates = []
    for iou, R, c in refined[:refine]:
        _check(cancel)
        start = np.array([*(c - R @ mesh.centroid), *angles_from_matrix(R)])
        candidates.append((iou, start))
        res = match(problem, start, settings, cancel=cancel)
        if res.cancelled:
            raise SearchCancelled
        if best_res is None or res.objective_mm < best_res.objective_mm:
            best_res = res
        done += 1
        if progress is not None:
            progress(done, total)
    iou_full = mask_iou(mesh, best_res.pose, views, masks, scale=0.5)
    if progress is not None:
        progress(total, total)
    return SearchResult(best_res.pose, best_res.objective_mm, iou_full, refined[0][0], best_res,
                        time.perf_counter() - t0, candidates)


def search_pose(mesh: PreparedMesh, views: Sequence[View], masks: Sequence[np.ndarray], n_orientations: int = 800,
                progress: ProgressCallback | None = None, cancel: Callable[[], bool] | None = None,
                **kwargs) -> np.ndarray:
    """Pose (x, y, z, alpha, beta, gamma; mm, deg) of ``mesh`` found from its masks in two
    views by a global search (see ``search_component`` for the details and options)."""
    return search_component(mesh, views, masks, n_orientations, progress=progress, cancel=cancel, **kwargs).pose


# -- which blob is which component -----------------------------------------------------------------
def blob_pairs(views: Sequence[View], blobs1: Sequence[Blob], blobs2: Sequence[Blob],
               max_miss_mm: float = 25.0) -> list[tuple[int, int, float]]:
    """Pairs (i, j, miss) of blobs whose centroid rays pass within ``max_miss_mm``, closest first."""
    out = []
    for i, a in enumerate(blobs1):
        for j, b in enumerate(blobs2):
            _, miss = triangulate(views, [a.centroid, b.centroid])
            if miss <= max_miss_mm:
                out.append((i, j, float(miss)))
    return sorted(out, key=lambda p: p[2])


@dataclass
class Assignment:
    component: str
    blob_indices: tuple[int, int]
    result: SearchResult


def _assignment_score(r: SearchResult) -> float:
    # lower is better: matcher objective (mm) penalised by the silhouette misfit
    return r.objective_mm + 2.0 * (1.0 - r.mean_iou)


def assign_blobs(meshes: dict, views: Sequence[View], blobs: Sequence[Sequence[Blob]], max_blobs: int = 4,
                 max_miss_mm: float = 25.0, progress: Callable[[str], None] | None = None,
                 cancel: Callable[[], bool] | None = None, **search_kwargs) -> dict[str, Assignment]:
    """Decide which blob in each view is which component and find its pose.

    ``meshes`` maps a component name to its PreparedMesh; ``blobs`` are the two views'
    blob lists (largest first; the first ``max_blobs`` are tried). Every component is
    searched on every plausible pair; the assignment (no blob used twice) with the lowest
    summed score (objective in mm plus 2 x (1 - mean IoU)) is returned, name -> Assignment."""
    b1, b2 = list(blobs[0])[:max_blobs], list(blobs[1])[:max_blobs]
    pairs = blob_pairs(views, b1, b2, max_miss_mm)
    if not pairs:
        raise ValueError("no blob pair in the two views images the same place")
    trials: dict[tuple[str, int, int], SearchResult] = {}
    for name, mesh in meshes.items():
        for i, j, _ in pairs:
            if progress is not None:
                progress(f"{name}: blobs {i} / {j}")
            trials[(name, i, j)] = search_component(mesh, views, [b1[i].mask, b2[j].mask], cancel=cancel,
                                                    **search_kwargs)
    names = list(meshes)
    best, best_score = None, np.inf
    for combo in itertools.permutations(pairs, len(names)) if len(pairs) >= len(names) else []:
        used1 = [p[0] for p in combo]
        used2 = [p[1] for p in combo]
        if len(set(used1)) < len(used1) or len(set(used2)) < len(used2):
            continue
        score = sum(_assignment_score(trials[(n, p[0], p[1])]) for n, p in zip(names, combo))
        if score < best_score:
            best, best_score = combo, score
    if best is None:  # fewer disjoint pairs than components: greedily, best fits first
        out: dict[str, Assignment] = {}
        used1, used2 = set(), set()
        for (n, i, j), r in sorted(trials.items(), key=lambda kv: _assignment_score(kv[1])):
            if n in out or i in used1 or j in used2:
                continue
            out[n] = Assignment(n, (i, j), r)
            used1.add(i)
            used2.add(j)
        return out
    return {n: Assignment(n, (p[0], p[1]), trials[(n, p[0], p[1])]) for n, p in zip(names, best)}


# -- the one entry point for "find implants" lives in find.py ----------------------------------------
def __getattr__(name):
    """``Placement`` and ``find_components`` (fluorogui.core.find) are importable from here
    too; imported lazily because find.py imports this module."""
    if name in ("Placement", "find_components"):
        from . import find

        return getattr(find, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
