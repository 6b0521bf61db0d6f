"""Image outlines of a component: Canny edges, linked edge chains, sub-pixel localisation,
and the choice (or assembly) of the chain that outlines a predicted component.

Points are pixel coordinates (u, v) = (column, row), origin at the centre of the top-left
pixel. Sub-pixel localisation moves every edge pixel to the maximum of the smoothed
gradient magnitude along the gradient direction (after Devernay 1995: samples at -1, 0,
+1 px along the gradient with bilinear interpolation, and a parabola through their
logarithm, which is exact for a Gaussian-blurred step); on blurred, noisy renderings its
mean offset from the true boundary is about a hundredth of a pixel.
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import cKDTree

from fluorogui.core.outlines.quantile import tail_percentile
from fluorogui.core.outlines.spline import outward_normals, resample_closed_polyline, untangle_outline

#: fraction of the reference gradient (see ``canny_edges``) used by default
DEFAULT_LOW, DEFAULT_HIGH = 0.1, 0.3


class EdgeError(ValueError):
    """No usable outline could be found in an image."""


# -- gradients and Canny ---------------------------------------------------------------------
def smoothed_gradients(image: np.ndarray, sigma: float = 1.0):
    """Gaussian-smoothed image and its derivatives d/du, d/dv (Sobel, scaled to per pixel)."""
    img = np.asarray(image, dtype=np.float32)
    if sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    # (scale 1/8 inside the filter: a power of two, so the same numbers as dividing after)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, scale=0.125, borderType=cv2.BORDER_REFLECT)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, scale=0.125, borderType=cv2.BORDER_REFLECT)
    return img, gx, gy


def gradient_magnitude(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """float32 ``np.hypot(gx, gy)`` of finite float32 gradients, in float64 rounded once: glibc's
    hypotf does just this, and numpy's float32 hypot calls it element by element
    (twice as slow). Held to ``np.hypot`` by the tests."""
    if gx.dtype != np.float32 or gy.dtype != np.float32:
        return np.hypot(gx, gy)
    total = np.square(gx, dtype=np.float64)
    total += np.square(gy, dtype=np.float64)
    return np.sqrt(total, out=total).astype(np.float32)


def canny_edges(image: np.ndarray, low: float = DEFAULT_LOW, high: float = DEFAULT_HIGH, sigma: float = 1.0, *,
                roi: tuple[int, int, int, int] | None = None, gradients=None, magnitude=None) -> np.ndarray:
    """Boolean Canny edge map of a float image.

    The image is smoothed with a Gaussian of ``sigma`` px and its float gradients are
    passed to cv2.Canny as 16-bit derivatives (no 8-bit quantisation of the image).
    ``low`` and ``high`` are fractions of a reference gradient: the 99.9th percentile of
    the gradient magnitude, taken inside ``roi`` (u0, v0, u1, v1) when given. A component's
    outline covers well over 0.1 % of a region around it, so the reference is an edge
    gradient, not noise, and a single very strong edge does not dominate it.
    ``gradients`` (``smoothed_gradients(image, sigma)``) and ``magnitude`` (their hypot)
    save computing them again where the caller has them.
    """
    if not 0 < low <= high:
        raise ValueError("Canny thresholds must satisfy 0 < low <= high")
    _, gx, gy = gradients if gradients is not None else smoothed_gradients(image, sigma)
    mag = magnitude if magnitude is not None else gradient_magnitude(gx, gy)
    return canny_from(canny_derivatives(gx, gy, mag, roi), low, high)


def canny_derivatives(gx: np.ndarray, gy: np.ndarray, magnitude: np.ndarray,
                      roi: tuple[int, int, int, int] | None = None):
    """The 16-bit derivatives ``canny_edges`` passes to cv2.Canny (the gradients scaled so
    that the reference gradient is 8000), or the empty edge map where the image is flat;
    made once, they serve any thresholds (``canny_from``)."""
    region = magnitude
    if roi is not None:
        u0, v0, u1, v1 = (int(round(x)) for x in roi)
        region = magnitude[max(v0, 0):max(v1, 0), max(u0, 0):max(u1, 0)]
        if region.size == 0:
            region = magnitude
    reference = tail_percentile(region, 99.9) or float(magnitude.max())
    if reference <= 0:
        return np.zeros(magnitude.shape, dtype=bool)
    scale = 8000.0 / reference  # reference gradient -> 8000 of int16's 32767
    out = []
    for g in (gx, gy):  # round and clip in place: the same numbers as np.clip(np.round(g * scale))
        scaled = np.multiply(g, scale)
        np.rint(scaled, out=scaled)
        np.minimum(scaled, 32767, out=scaled)
        np.maximum(scaled, -32767, out=scaled)
        out.append(scaled.astype(np.int16))
    return tuple(out)


def canny_from(derivatives, low: float, high: float) -> np.ndarray:
    """Canny edge map from ``canny_derivatives`` with thresholds ``low``, ``high`` (fractions
    of the reference gradient)."""
    if isinstance(derivatives, np.ndarray):  # a flat image: no edges
        return derivatives.copy()
    dx, dy = derivatives
    return cv2.Canny(dx, dy, low * 8000.0, high * 8000.0, L2gradient=True) > 0


# -- sub-pixel localisation ------------------------------------------------------------------
def subpixel_edges(gx: np.ndarray, gy: np.ndarray, pixels: np.ndarray, *, max_shift: float = 1.0,
                   fit: str = "gaussian", magnitude: np.ndarray | None = None):
    """Move edge pixels (K, 2) to the gradient-magnitude maximum along the gradient.

    The peak is found from the magnitude sampled at -1, 0, +1 px along the gradient
    (bilinear interpolation). ``fit`` "parabola" fits the magnitude itself (Devernay 1995),
    which pulls the estimate towards the pixel by up to ~0.04 px for the usual blur and,
    because Canny's non-maximum suppression favours one side of an edge, biases the mean;
    "gaussian" (default) fits the log-magnitude, exact for a Gaussian-blurred step.

    ``magnitude`` (float32 hypot of gx, gy) saves computing it again.

    Returns refined points (K, 2) and the gradient vectors (K, 2) at the pixels."""
    pixels = np.asarray(pixels, dtype=float).reshape(-1, 2)
    if len(pixels) == 0:
        return pixels.copy(), pixels.copy()
    mag = magnitude if magnitude is not None else np.hypot(gx, gy).astype(np.float32)
    col = np.clip(np.round(pixels[:, 0]).astype(int), 0, mag.shape[1] - 1)
    row = np.clip(np.round(pixels[:, 1]).astype(int), 0, mag.shape[0] - 1)
    grad = np.column_stack([gx[row, col], gy[row, col]]).astype(float)
    direction = grad / np.maximum(np.linalg.norm(grad, axis=1, keepdims=True), 1e-12)
    samples = []
    # cv2.remap takes maps of fewer than 32767 columns: lay the samples out in rows
    k = len(pixels)
    width = min(k, 4096)
    rows = -(-k // width)
    map_u, map_v = np.zeros((2, rows * width), dtype=np.float32)  # the padding stays 0 (np.pad's, cheaper)
    for step in (-1.0, 0.0, 1.0):
        map_u[:k] = pixels[:, 0] + step * direction[:, 0]
        map_v[:k] = pixels[:, 1] + step * direction[:, 1]
        sampled = cv2.remap(mag, map_u.reshape(rows, width), map_v.reshape(rows, width), cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_REFLECT)
        samples.append(sampled.reshape(-1)[:k].astype(float))
    before, centre, after = samples
    if fit == "gaussian":  # a parabola through the log-magnitude is exact for a Gaussian peak
        before, centre, after = (np.log(np.maximum(x, 1e-12)) for x in samples)
    elif fit != "parabola":
        raise ValueError(f"unknown fit {fit!r}; use 'gaussian' or 'parabola'")
    curvature = before - 2.0 * centre + after
    peaked = curvature < -1e-12
    offset = np.where(peaked, 0.5 * (before - after) / np.where(peaked, curvature, -1.0), 0.0)
    offset = np.clip(offset, -max_shift, max_shift)
    return pixels + offset[:, None] * direction, grad


# -- linking edge pixels into chains ----------------------------------------------------------
def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of the runs of True in a boolean array."""
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    change = np.flatnonzero(np.diff(padded))
    return list(zip(change[0::2], change[1::2]))


def _pixel_chains(edge_mask: np.ndarray) -> list[tuple[np.ndarray, bool]]:
    """Edge pixels linked into ordered chains (pixel (u, v) integer arrays, closed flag).

    cv2.findContours walks around a one-pixel-wide curve, so an open curve is traced out
    and back and a closed one twice (outer and hole contour); keeping only pixels not yet
    visited visits every pixel once. Chains whose ends touch are joined afterwards."""
    mask = np.ascontiguousarray(edge_mask, dtype=np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    width = mask.shape[1]
    visited = np.zeros(mask.size, dtype=bool)
    chains: list[tuple[np.ndarray, bool]] = []
    for contour in contours:
        pts = contour[:, 0, :]
        index = pts[:, 1].astype(np.int64) * width + pts[:, 0]
        _, first = np.unique(index, return_index=True)
        fresh = np.zeros(len(pts), dtype=bool)
        fresh[first] = True
        fresh &= ~visited[index]
        visited[index] = True
        if fresh.all():
            closed = len(pts) > 2 and np.max(np.abs(pts[0] - pts[-1])) <= 1
            chains.append((pts.copy(), bool(closed)))
            continue
        runs = _runs(fresh)
        if len(runs) > 1 and runs[0][0] == 0 and runs[-1][1] == len(pts):
            # the run wrapping past the end of the contour continues at its start
            (s0, e0), (s1, e1) = runs[0], runs[-1]
            chains.append((np.vstack([pts[s1:e1], pts[s0:e0]]), False))
            runs = runs[1:-1]
        chains.extend((pts[s:e].copy(), False) for s, e in runs)
    return _join_touching_chains(chains)


def _join_touching_chains(chains):
    """Join open chains whose end pixels are 8-neighbours (and close chains that meet
    themselves); greedy, nearest ends first."""
    chains = [(c, closed) for c, closed in chains if len(c)]
    changed = True
    while changed:
        changed = False
        open_ids = [i for i, (c, closed) in enumerate(chains) if not closed]
        if not open_ids:
            break
        ends = np.array([chains[i][0][j] for i in open_ids for j in (0, -1)], dtype=float)
        owners = np.repeat(open_ids, 2)
        tree = cKDTree(ends)
        for a, b in sorted(tree.query_pairs(1.5), key=lambda ab: np.linalg.norm(ends[ab[0]] - ends[ab[1]])):
            i, j = owners[a], owners[b]
            if i == j:
                if len(chains[i][0]) > 2:
                    chains[i] = (chains[i][0], True)
                    changed = True
                    break
                continue
            ci = chains[i][0] if a % 2 == 1 else chains[i][0][::-1]  # end of i at the tail
            cj = chains[j][0] if b % 2 == 0 else chains[j][0][::-1]  # end of j at the head
            chains[i] = (np.vstack([ci, cj]), False)
            del chains[j]
            changed = True
            break
    return chains


def _drop_backtracking(points: np.ndarray, closed: bool) -> np.ndarray:
    """Remove points that step backwards along the chain (sub-pixel points of a staircase
    can swap order); the direction is taken over +-2 neighbours."""
    if len(points) < 5:
        return points
    if closed:
        ahead, behind = np.roll(points, -2, axis=0), np.roll(points, 2, axis=0)
        step_next = np.roll(points, -1, axis=0) - points
    else:
        ahead = np.vstack([points[2:], np.repeat(points[-1:], 2, axis=0)])
        behind = np.vstack([np.repeat(points[:1], 2, axis=0), points[:-2]])
        step_next = np.vstack([np.diff(points, axis=0), [[1e-9, 0.0]]])
    direction = ahead - behind
    keep = np.einsum("ij,ij->i", step_next, direction) > 0
    if not closed:
        keep[-1] = True
    return points[keep]


def edge_contours(image: np.ndarray, low: float = DEFAULT_LOW, high: float = DEFAULT_HIGH, sigma: float = 1.0, *,
                  min_length_px: int = 20, subpixel: bool = True, roi=None) -> list[np.ndarray]:
    """Canny edges linked into ordered chains (K, 2) of (u, v), each edge pixel once, at
    sub-pixel precision unless ``subpixel`` is False. A closed chain's first and last points
    are neighbours (the first point is not repeated). Where Canny's edge is two pixels thick
    the extra pixels come as short side chains (down to single points): they are kept, as
    dropping them would drop one side of the edge and bias it; ``min_length_px`` applies to
    the connected edge a chain belongs to. Sub-pixel points that would step backwards
    along a chain are removed."""
    edges = canny_edges(image, low, high, sigma, roi=roi)
    chains = _pixel_chains(edges)
    _, labels, stats, _ = cv2.connectedComponentsWithStats(edges.astype(np.uint8), connectivity=8)
    size = stats[:, cv2.CC_STAT_AREA]
    chains = [(c, closed) for c, closed in chains if size[labels[c[0, 1], c[0, 0]]] >= min_length_px]
    if not chains:
        return []
    if not subpixel:
        return [c.astype(float) for c, _ in chains]
    _, gx, gy = smoothed_gradients(image, sigma)
    refined, _ = subpixel_edges(gx, gy, np.vstack([c for c, _ in chains]).astype(float))
    pieces = np.split(refined, np.cumsum([len(c) for c, _ in chains])[:-1])
    return [_drop_backtracking(p, closed) for p, (_, closed) in zip(pieces, chains)]


# -- choosing the component's outline --------------------------------------------------------
def _arc_parameter(polyline: np.ndarray):
    """Closed polyline resampled at ~0.5 px, its cumulative arc length and total length."""
    dense = resample_closed_polyline(polyline, spacing=0.5)
    step = np.linalg.norm(np.diff(np.vstack([dense, dense[:1]]), axis=0), axis=1)
    return dense, np.concatenate([[0.0], np.cumsum(step)[:-1]]), float(step.sum())


class _Along:
    """A predicted closed outline resampled densely (``_arc_parameter``) with its k-d tree and
    outward normals: made once per prediction and shared by the steps that measure edge
    points against it (each used to resample it and build its tree again)."""

    def __init__(self, predicted_px: np.ndarray):
        self.dense, self.arc, self.total = _arc_parameter(np.asarray(predicted_px, dtype=float))
        self.tree = cKDTree(self.dense)
        self._normals = None
        self._bin_pixels = {}

    @property
    def normals(self) -> np.ndarray:
        if self._normals is None:
            self._normals = outward_normals(self.dense)
        return self._normals

    def query(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance to, and index of, each point's nearest dense sample."""
        return self.tree.query(points)

    def bin_pixels(self, n_bins: int, shape) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) of the pixel at the centre of each of ``n_bins`` equal bins along the
        outline, clipped to an image of ``shape`` (kept: ``uncovered_arc`` asks again)."""
        key = (n_bins, tuple(shape[:2]))
        if key not in self._bin_pixels:
            dense = self.dense
            centre = np.interp((np.arange(n_bins) + 0.5) * self.total / n_bins, self.arc, np.arange(len(dense)))
            at = dense[np.clip(np.round(centre).astype(int), 0, len(dense) - 1)]
            col = np.clip(np.round(at[:, 0]).astype(int), 0, shape[1] - 1)
            row = np.clip(np.round(at[:, 1]).astype(int), 0, shape[0] - 1)
            self._bin_pixels[key] = (row, col)
        return self._bin_pixels[key]


def contour_fit(contour: np.ndarray, predicted_px: np.ndarray, tolerance_px: float = 8.0) -> float:
    """Mismatch (px, lower is better) of a contour with a predicted closed outline: the mean
    distance from predicted points to the contour plus from contour points to the
    prediction, each distance capped at ``tolerance_px`` so that uncovered parts of the
    prediction and stray parts of the contour cost the same fixed amount."""
    contour = np.asarray(contour, dtype=float)
    pred = resample_closed_polyline(predicted_px, spacing=1.0)
    d_pred, _ = cKDTree(contour).query(pred)
    dense, _, _ = _arc_parameter(predicted_px)
    d_cont, _ = cKDTree(dense).query(contour)
    return float(np.mean(np.minimum(d_pred, tolerance_px)) + np.mean(np.minimum(d_cont, tolerance_px)))


def select_outline(contours: list[np.ndarray], predicted_px: np.ndarray, merge: bool = False,
                   tolerance_px: float = 8.0) -> np.ndarray:
    """The contour that best fits a predicted outline (``contour_fit``), or with ``merge``
    the pieces of all contours lying within ``tolerance_px`` of it joined into one closed
    outline ordered along the prediction (Canny often breaks an outline into pieces)."""
    contours = [np.asarray(c, dtype=float) for c in contours if len(c) >= 2]
    predicted_px = np.asarray(predicted_px, dtype=float)
    if not contours:
        raise EdgeError("there are no edge contours to choose from")
    if not merge:
        scores = [contour_fit(c, predicted_px, tolerance_px) for c in contours]
        return contours[int(np.argmin(scores))]
    return _merge_along(contours, predicted_px, tolerance_px)


def _merge_along(contours, predicted_px, tolerance_px, *, bin_px: float = 1.0, pieces=None, along=None,
                 near=None) -> np.ndarray:
    """Points of contours near the prediction, ordered along it: every ``bin_px`` of the
    prediction's arc is served by the piece (a contour, or the given ``pieces`` label per
    point) lying closest to the prediction on average, and the points of that piece in the
    bin are averaged into one, so parallel duplicates cannot zigzag. ``along`` (the
    prediction's ``_Along``) and ``near`` (the points' ``along.query``) save making them."""
    points = np.vstack(contours)
    if pieces is None:
        pieces = np.repeat(np.arange(len(contours)), [len(c) for c in contours])
    along = along or _Along(predicted_px)
    arc, total = along.arc, along.total
    dist, nearest = near if near is not None else along.query(points)
    near = dist <= tolerance_px
    points, dist, params, pieces = points[near], dist[near], arc[nearest[near]], np.asarray(pieces)[near]
    if len(points) < 4:
        raise EdgeError("no edge contour lies along the predicted outline")
    _, pieces = np.unique(pieces, return_inverse=True)
    piece_residual = np.bincount(pieces, weights=dist) / np.bincount(pieces)
    n_bins = max(4, int(np.ceil(total / bin_px)))
    bins = np.minimum((params / total * n_bins).astype(int), n_bins - 1)
    order = np.lexsort((piece_residual[pieces], bins))
    first_in_bin = np.concatenate([[True], bins[order][1:] != bins[order][:-1]])
    winner = np.full(n_bins, -1)
    winner[bins[order][first_in_bin]] = pieces[order][first_in_bin]
    keep = winner[bins] == pieces
    count = np.bincount(bins[keep], minlength=n_bins)
    filled = count > 0
    outline = np.column_stack(
        [np.bincount(bins[keep], weights=points[keep, axis], minlength=n_bins)[filled] for axis in (0, 1)]
    ) / count[filled][:, None]
    if len(outline) < 4:
        raise EdgeError("too few edge points along the predicted outline")
    return outline


def outline_from_mask(mask: np.ndarray, offset_px: float = 0.0) -> np.ndarray:
    """Ordered outer boundary (K, 2) of the largest region of a binary mask: the centres of
    its boundary pixels, pushed outwards by ``offset_px`` (0.5 puts it on the pixel edges,
    where the boundary of a thresholded region lies)."""
    contours, _ = cv2.findContours(np.asarray(mask, dtype=np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        raise EdgeError("the mask is empty")
    pts = max(contours, key=cv2.contourArea)[:, 0, :].astype(float)
    if offset_px and len(pts) >= 3:
        tangent = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
        normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        area2 = np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
        pts = pts + offset_px * (normal if area2 > 0 else -normal)
    return pts


# -- the whole path ----------------------------------------------------------------------------
def best_translation(edge_mask: np.ndarray, predicted_px: np.ndarray, search_px: int = 60) -> np.ndarray:
    """Shift (du, dv) of the predicted outline that best fits an edge map (mean capped
    chamfer distance), coarse to fine over +-``search_px``."""
    distance = np.minimum(cv2.distanceTransform((~edge_mask).astype(np.uint8), cv2.DIST_L2, 5), 20.0)
    height, width = distance.shape
    pts = resample_closed_polyline(predicted_px, n=min(300, max(8, len(predicted_px))))

    flat = distance.reshape(-1)

    def costs(best: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """Mean distance at the points shifted by ``best`` + (du, dv) for every du, dv of
        ``offsets`` (du outer): a point's rounded column depends on du alone and its row on
        dv alone, so each is rounded once per offset, not once per shift."""
        du, dv = best[0] + offsets.astype(float), best[1] + offsets.astype(float)
        u = np.minimum(np.maximum(np.round(pts[None, :, 0] + du[:, None]).astype(int), 0), width - 1)
        v = np.minimum(np.maximum(np.round(pts[None, :, 1] + dv[:, None]).astype(int), 0), height - 1)
        index = (v * width)[None, :, :] + u[:, None, :]  # (du, dv, point)
        return flat[index.reshape(len(du) * len(dv), -1)].mean(axis=1)

    best = np.zeros(2)
    for step, reach in ((8, search_px), (2, 8), (1, 2)):
        offsets = np.arange(-reach, reach + 1, step)
        i = int(np.argmin(costs(best, offsets)))  # first minimum, as min() over the list did
        best = best + np.array([offsets[i // len(offsets)], offsets[i % len(offsets)]], dtype=float)
    return best


class _EdgeMap:
    """An edge map with its connected-edge labels and its pixels (row-major, as ``np.nonzero``),
    each made once and shared by the predictions measured against the map."""

    def __init__(self, mask: np.ndarray):
        self.mask = mask
        self._labels = self._pixels = None

    @property
    def labels(self) -> np.ndarray:
        if self._labels is None:
            self._labels = cv2.connectedComponents(self.mask.astype(np.uint8), connectivity=8)[1]
        return self._labels

    @property
    def pixels(self) -> tuple[np.ndarray, np.ndarray]:
        if self._pixels is None:
            self._pixels = np.nonzero(self.mask)
        return self._pixels


def _dark_edge_points(image, edges, predicted, sigma, *, polarity, gradients=None, within_px=None, along=None,
                      magnitude=None, band=None):
    """Sub-pixel points of the pixels of an edge map, their connected-edge labels (of the
    whole map), whether each has the expected polarity relative to the predicted
    outline, and each point's ``along.query`` (distance to the prediction's dense samples
    and the nearest one's index); with ``within_px``, only of the pixels that may lie that
    close to the prediction once refined (noise gives a weak edge map tens of thousands of
    pixels). ``edges`` is a boolean image or its ``_EdgeMap``; ``along`` (the prediction's
    ``_Along``), ``gradients``, ``magnitude`` and ``band`` (``_band`` of the prediction and
    ``within_px``) are made here when not given."""
    edge_map = edges if isinstance(edges, _EdgeMap) else _EdgeMap(edges)
    rows, cols = edge_map.pixels
    if within_px is not None:  # the pixels of the map in the band (as nonzero(edges & band), without the image)
        if band is None:
            band = _band(edge_map.mask.shape, predicted, within_px)
        inside = band[rows, cols]
        rows, cols = rows[inside], cols[inside]
    labels = edge_map.labels
    _, gx, gy = gradients if gradients is not None else smoothed_gradients(image, sigma)
    refined, grad = subpixel_edges(gx, gy, np.column_stack([cols, rows]).astype(float), magnitude=magnitude)
    if polarity not in ("dark", "any"):
        raise ValueError(f"unknown polarity {polarity!r}; use 'dark' or 'any'")
    along = along or _Along(predicted)
    near = along.query(refined) if len(refined) else (np.zeros(0), np.zeros(0, dtype=int))
    if polarity == "dark":
        outward = along.normals[near[1]]
        agrees = np.einsum("ij,ij->i", grad, outward) > 0.5 * np.linalg.norm(grad, axis=1)
    else:
        agrees = np.ones(len(refined), dtype=bool)
    return refined, labels[rows, cols], agrees, near


def _band(shape, predicted: np.ndarray, within_px: float) -> np.ndarray:
    """Pixels (boolean image of ``shape``) that lie within ``within_px`` of a closed
    outline, with room to spare: a refined edge point moves up to 1 px from its pixel
    (``subpixel_edges``) and the drawn line is rounded to whole pixels."""
    band = np.zeros(shape, dtype=np.uint8)
    polygon = np.round(np.asarray(predicted, dtype=float) * 4).astype(np.int32)  # 2 fractional bits
    cv2.polylines(band, [polygon], True, 1, thickness=2 * int(np.ceil(within_px + 3)) + 1, shift=2)
    return band > 0


def uncovered_arc(points: np.ndarray, predicted_px: np.ndarray, *, tolerance_px: float = 8.0,
                  bin_px: float = 1.0, min_gap_px: float = 6.0,
                  hidden: np.ndarray | None = None, along: _Along | None = None,
                  near: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Where a predicted closed outline has no edge point within ``tolerance_px``: the bin
    index of every given point's nearest arc position (``bin_px`` bins along the
    prediction) and a boolean flag per bin, True on runs of uncovered bins at least
    ``min_gap_px`` long (shorter runs are the normal breaks of an edge chain). Bins under
    ``hidden`` (a boolean image: another component's area) are expected to be bare and
    never count as uncovered. ``along`` (the prediction's ``_Along``) and ``near`` (the
    points' ``along.query``) save making them again."""
    along = along or _Along(predicted_px)
    arc, total = along.arc, along.total
    n_bins = max(4, int(np.ceil(total / bin_px)))
    covered = np.zeros(n_bins, dtype=bool)
    if hidden is not None:
        row, col = along.bin_pixels(n_bins, hidden.shape)
        covered |= hidden[row, col]
    bins = np.zeros(0, dtype=int)
    if len(points):
        dist, nearest = near if near is not None else along.query(points)
        bins = np.minimum((arc[nearest] / total * n_bins).astype(int), n_bins - 1)
        covered[bins[dist <= tolerance_px]] = True
    gap = ~covered
    if gap.all() or not gap.any():
        return bins, gap
    # runs of uncovered bins on the closed outline (rotate so a covered bin comes first)
    shift = int(np.flatnonzero(covered)[0])
    rolled = np.roll(gap, -shift)
    if min_gap_px <= 0:  # every run is long enough
        return bins, gap
    padded = np.zeros(n_bins + 2, dtype=np.int8)
    padded[1:-1] = rolled
    start, stop = np.flatnonzero(np.diff(padded)).reshape(-1, 2).T  # the runs of ``_runs``
    long_enough = (stop - start) * total / n_bins >= min_gap_px  # (the same operations, per run)
    # mark the long runs' first bins +1 and the bins after them -1: their running sum is 1 on them
    marks = np.zeros(n_bins + 1, dtype=np.int64)
    marks[start[long_enough]] = 1
    marks[stop[long_enough]] -= 1
    keep = np.cumsum(marks[:-1]) > 0
    return bins, np.roll(keep, shift)


def component_outline(image: np.ndarray, predicted_px: np.ndarray, *, sigma: float = 1.0, tolerance_px: float = 8.0,
                      polarity: str = "dark", search_px: int = 60, low: float = DEFAULT_LOW,
                      high: float = DEFAULT_HIGH, gap_fill: tuple[float, float] | None = (0.04, 0.12),
                      min_gap_px: float = 6.0, exclude: np.ndarray | None = None) -> np.ndarray:
    """Ordered, closed, sub-pixel outline (K, 2) of the component predicted at ``predicted_px``
    (e.g. the projected model outline at the start pose).

    Canny runs in a region around the prediction; the prediction is first translated to
    the best chamfer fit within ``search_px`` (a start pose a few mm off), the sub-pixel edge
    chains within ``tolerance_px`` of it are kept, and with ``polarity`` "dark" only edges
    whose intensity rises outwards (a dark component on a brighter surround) - "any" keeps
    all; the pieces are then merged along the prediction.

    Canny's thresholds are fractions of the strongest gradients around the prediction,
    so a faint part of the outline next to a strong one (a tibial keel in bone beside the
    tray and the femoral component) can fall below them and the outline would bridge it
    with a chord. With ``gap_fill`` (low, high), every run of the prediction at least
    ``min_gap_px`` long that no edge covers is searched again in a Canny map with these
    lower thresholds, and only the weak edges found in those runs are added; where the
    default edges cover the whole prediction the result is unchanged. When the default
    edges leave gaps, the chamfer fit may have slid the prediction onto other strong
    edges (skin against the bright background); the fit to the weak edge map is tried
    too and the shift leaving less of the prediction uncovered is kept. ``None`` turns
    both off.

    ``exclude`` (a boolean mask of the image's shape) removes the edges under it: the
    region of another component that overlaps this one, whose edges must not pull the
    outline (the matcher ignores the outline there too). All the work is done on a crop
    around the prediction, so the cost does not grow with the image size.
    """
    predicted = np.asarray(predicted_px, dtype=float)
    if predicted.ndim != 2 or len(predicted) < 4:
        raise EdgeError("the predicted outline needs at least 4 points")
    image = np.asarray(image)
    margin = search_px + tolerance_px + 4 * sigma
    lo, hi = predicted.min(axis=0) - margin, predicted.max(axis=0) + margin
    pad = int(np.ceil(4 * sigma)) + 4  # so the smoothing inside the region sees real pixels
    height, width = image.shape[:2]
    u0, v0 = max(int(np.floor(lo[0])) - pad, 0), max(int(np.floor(lo[1])) - pad, 0)
    u1, v1 = min(int(np.ceil(hi[0])) + 1 + pad, width), min(int(np.ceil(hi[1])) + 1 + pad, height)
    if u1 - u0 < 8 or v1 - v0 < 8:
        raise EdgeError("the predicted outline lies outside the image")
    offset = np.array([u0, v0], dtype=float)
    crop = image[v0:v1, u0:u1]
    roi = (int(np.floor(lo[0])) - u0, int(np.floor(lo[1])) - v0, int(np.ceil(hi[0])) + 1 - u0,
           int(np.ceil(hi[1])) + 1 - v0)
    keep = None if exclude is None else ~np.asarray(exclude, dtype=bool)[v0:v1, u0:u1]
    outline = _outline_in_region(crop, predicted - offset, roi, keep, sigma=sigma, tolerance_px=tolerance_px,
                                 polarity=polarity, search_px=search_px,
                                 low=low, high=high, gap_fill=gap_fill, min_gap_px=min_gap_px)
    return outline + offset


def _outline_in_region(image, predicted, roi, keep, *, sigma, tolerance_px, polarity, search_px, low, high, gap_fill,
                       min_gap_px) -> np.ndarray:
    """``component_outline`` in the coordinates of an image crop; ``keep`` masks usable edges."""
    gradients = smoothed_gradients(image, sigma)  # shared by both Canny maps and the sub-pixel step
    magnitude = gradient_magnitude(gradients[1], gradients[2])
    if not 0 < low <= high:
        raise ValueError("Canny thresholds must satisfy 0 < low <= high")
    derivatives = canny_derivatives(gradients[1], gradients[2], magnitude, roi)  # for both maps
    edges = canny_from(derivatives, low, high)
    hidden = None
    if keep is not None:
        edges &= keep
        hidden = ~keep
    if not edges.any():
        raise EdgeError("the image has no edges near the predicted outline")
    weak_map = []

    def weak_edges():
        if not weak_map:
            if not 0 < gap_fill[0] <= gap_fill[1]:
                raise ValueError("Canny thresholds must satisfy 0 < low <= high")
            weak = canny_from(derivatives, gap_fill[0], gap_fill[1])
            inside = np.zeros_like(weak)
            inside[max(roi[1], 0):max(roi[3], 0), max(roi[0], 0):max(roi[2], 0)] = True
            weak_map.append(weak & inside if keep is None else weak & inside & keep)
        return weak_map[0]

    edge_map = _EdgeMap(edges)
    weak_only = []  # the weak map's edges that are not default edges, as an _EdgeMap

    def weak_only_edges():
        if not weak_only:
            weak_only.append(_EdgeMap(weak_edges() & ~edges))
        return weak_only[0]

    def gather(shift):
        """Edge points along the prediction shifted by ``shift``: the shifted prediction, the
        points, their pieces, whether the default edges left gaps, how many 1 px bins stay
        uncovered, the prediction's ``_Along`` and the points' queries against it."""
        pred = predicted + shift
        along = _Along(pred)
        # every Canny pixel counts (no chain linking, which drops pixels where Canny's
        # edge is two pixels thick); pieces are the connected edges
        # points farther than tolerance_px from the prediction count nowhere (not as
        # cover, left out of the merge): only those near are refined
        band = _band(edges.shape, pred, tolerance_px)  # (for both edge maps)
        refined, labels, agrees, near = _dark_edge_points(image, edge_map, pred, sigma, polarity=polarity,
                                                          gradients=gradients, within_px=tolerance_px, along=along,
                                                          magnitude=magnitude, band=band)
        points, pieces = refined[agrees], labels[agrees]
        near = (near[0][agrees], near[1][agrees])
        had_gaps = False
        if gap_fill is not None:
            _, gap = uncovered_arc(points, pred, tolerance_px=tolerance_px, min_gap_px=min_gap_px, hidden=hidden,
                                   along=along,
                                   near=near)
            had_gaps = bool(gap.any())
            weak = weak_only_edges() if had_gaps else None
            if had_gaps and len(weak.pixels[0]):
                w_points, w_labels, w_agrees, w_near = _dark_edge_points(image, weak, pred, sigma, polarity=polarity,
                                                                         gradients=gradients, within_px=tolerance_px,
                                                                         along=along, magnitude=magnitude, band=band)
                w_bins, _ = uncovered_arc(w_points, pred, tolerance_px=tolerance_px, min_gap_px=min_gap_px, along=along,
                                          near=w_near)
                use = w_agrees & gap[w_bins]
                points = np.vstack([points, w_points[use]])
                pieces = np.concatenate([pieces, w_labels[use] + (int(labels.max()) + 1 if len(labels) else 0)])
                near = (np.concatenate([near[0], w_near[0][use]]), np.concatenate([near[1], w_near[1][use]]))
        _, left = uncovered_arc(points, pred, tolerance_px=tolerance_px, min_gap_px=0.0, hidden=hidden, along=along,
                                near=near)
        return pred, points, pieces, had_gaps, int(left.sum()), along, near

    shift = best_translation(edges, predicted, search_px) if search_px > 0 else np.zeros(2)
    found = gather(shift)
    if gap_fill is not None and search_px > 0 and found[3]:
        # the default edges miss part of the outline, so their chamfer fit may have slid
        # the prediction onto other edges (soft tissue): try the fit to the weak edges too
        # and keep whichever leaves less of the prediction uncovered
        weak_shift = best_translation(weak_edges(), predicted, search_px)
        if np.any(weak_shift != shift):
            other = gather(weak_shift)
            if other[4] < found[4]:
                found = other
    predicted, points, pieces, _, _, along, near = found
    if not len(points):
        raise EdgeError("no edge with the expected polarity near the predicted outline")
    outline = untangle_outline(_merge_along([points], predicted, tolerance_px, pieces=pieces, along=along,
                                            near=near))
    if len(outline) < 4:
        raise EdgeError("too few edge points along the predicted outline")
    return outline
