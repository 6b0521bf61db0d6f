"""Image outlines of a component: Canny edges, sub-pixel localisation, contour choice.

``component_outline(image, predicted)`` is the automatic path of the paper's "manually
reviewed" outline: Canny proposes edge contours; the prediction (the projected model
outline at a rough pose) is first slid over the edge map to the best chamfer fit, then
the contours lying along it are kept, every edge pixel is moved to the maximum of the
gradient magnitude along the gradient (a parabola through the log-magnitude at -1, 0,
+1 px, exact for Gaussian-blurred steps), and the points are ordered along the
prediction, one per pixel of its arc, preferring the strongest edge with the expected
polarity (a dark component on a brighter surround).
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import cKDTree


def smoothed_gradients(image: np.ndarray, sigma: float = 1.0):
    """Gaussian-smoothed image and its central-difference gradients (per pixel)."""
    img = np.asarray(image, dtype=np.float32)
    if sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT) / 8.0
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT) / 8.0
    return img, gx, gy


def canny_edges(image: np.ndarray, sigma: float = 1.0, high: float = 0.3, low: float = 0.4,
                roi: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """Canny edge mask. ``high`` is a fraction of the 99.9th percentile gradient, taken in
    ``roi`` (u0, v0, u1, v1) when given — around the component its edges are well over
    0.1 % of the pixels, so noise does not reach that level — and ``low`` a fraction of
    ``high``."""
    img, gx, gy = smoothed_gradients(image, sigma)
    lo_v, hi_v = float(np.min(img)), float(np.max(img))
    scale = 255.0 / max(hi_v - lo_v, 1e-6)
    dx = np.round(gx * 8.0 * scale * 4).astype(np.int16)  # cv2.Canny wants 16-bit derivatives
    dy = np.round(gy * 8.0 * scale * 4).astype(np.int16)
    mag = np.hypot(dx.astype(np.float32), dy.astype(np.float32))
    region = mag if roi is None else mag[max(roi[1], 0):roi[3], max(roi[0], 0):roi[2]]
    if region.size == 0:
        region = mag
    top = float(np.percentile(region, 99.9)) or float(region.max()) or 1.0
    return cv2.Canny(dx, dy, low * high * top, high * top, L2gradient=True) > 0


def subpixel_edges(gx: np.ndarray, gy: np.ndarray, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Move edge pixels (K, 2) as (u, v) to the gradient-magnitude peak along the gradient.

    Returns the refined points and the gradient vectors at the pixels."""
    mag = np.hypot(gx, gy).astype(np.float32)
    u, v = pixels[:, 0].astype(int), pixels[:, 1].astype(int)
    g = np.column_stack([gx[v, u], gy[v, u]]).astype(float)
    d = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-12)
    samples = []
    for s in (-1.0, 0.0, 1.0):
        map_x = (pixels[:, 0] + s * d[:, 0]).astype(np.float32).reshape(1, -1)
        map_y = (pixels[:, 1] + s * d[:, 1]).astype(np.float32).reshape(1, -1)
        samples.append(cv2.remap(mag, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)[0])
    lm, l0, lp = (np.log(np.maximum(x.astype(float), 1e-12)) for x in samples)
    denom = lm - 2 * l0 + lp
    offset = np.where(denom < -1e-12, 0.5 * (lm - lp) / np.where(denom < -1e-12, denom, -1.0), 0.0)
    offset = np.clip(offset, -1.0, 1.0)
    return pixels + offset[:, None] * d, g


def edge_contours(image: np.ndarray, sigma: float = 1.0, min_length_px: int = 20) -> list[np.ndarray]:
    """Canny edge chains as lists of pixel coordinates (u, v), each chain once."""
    edges = canny_edges(image, sigma).astype(np.uint8)
    n, labels = cv2.connectedComponents(edges, connectivity=8)
    if n <= 1:
        return []
    vs, us = np.nonzero(labels)
    lab = labels[vs, us]
    order = np.argsort(lab, kind="stable")
    splits = np.flatnonzero(np.diff(lab[order])) + 1
    chains = np.split(np.column_stack([us, vs])[order].astype(float), splits)
    return [c for c in chains if len(c) >= min_length_px]


def _dense_polyline(points: np.ndarray, spacing: float = 1.0) -> np.ndarray:
    closed = np.vstack([points, points[:1]])
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))]
    n = max(8, int(np.ceil(s[-1] / spacing)))
    t = np.arange(n) * s[-1] / n
    return np.column_stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])])


def _outward_normals(poly: np.ndarray) -> np.ndarray:
    tangent = np.roll(poly, -1, axis=0) - np.roll(poly, 1, axis=0)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    area = 0.5 * np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
    return normal if area > 0 else -normal  # image axes: v down, so positive area is clockwise


def best_shift(edge_mask: np.ndarray, predicted: np.ndarray, search_px: int = 60, step: int = 2) -> np.ndarray:
    """Translation of the predicted outline that best fits the edges (chamfer distance)."""
    dist = cv2.distanceTransform((~edge_mask).astype(np.uint8), cv2.DIST_L2, 5)
    dist = np.minimum(dist, 20.0)
    h, w = dist.shape
    pts = predicted[:: max(1, len(predicted) // 300)]
    best, best_cost = np.zeros(2), np.inf
    for s in (step * 4, step, 1):
        centre = best.copy()
        rng = search_px if s == step * 4 else s * 4
        offsets = np.arange(-rng, rng + 1, s)
        for du in offsets:
            u = np.clip(np.round(pts[:, 0] + centre[0] + du).astype(int), 0, w - 1)
            for dv in offsets:
                v = np.clip(np.round(pts[:, 1] + centre[1] + dv).astype(int), 0, h - 1)
                cost = float(dist[v, u].mean())
                if cost < best_cost:
                    best_cost, best = cost, centre + (du, dv)
    return best


def select_outline(contours: list[np.ndarray], predicted: np.ndarray, tolerance_px: float = 8.0,
                   min_fraction: float = 0.5) -> np.ndarray:
    """Pixels of the contours that lie along the predicted outline (their union)."""
    tree = cKDTree(_dense_polyline(predicted))
    keep = []
    for c in contours:
        d, _ = tree.query(c, distance_upper_bound=tolerance_px)
        if np.mean(np.isfinite(d)) >= min_fraction:
            keep.append(c[np.isfinite(d)])
    if not keep:
        raise ValueError("no edge contour lies along the predicted outline")
    return np.vstack(keep)


def order_along(points: np.ndarray, strength: np.ndarray, predicted: np.ndarray, bin_px: float = 1.0) -> np.ndarray:
    """One point per ``bin_px`` of the predicted outline's arc (the strongest), in its order,
    without isolated outliers."""
    poly = _dense_polyline(predicted, bin_px)
    d, idx = cKDTree(poly).query(points)
    order = np.lexsort((-strength, idx))
    first = np.r_[True, idx[order][1:] != idx[order][:-1]]
    chosen = order[first]
    pts, dist = points[chosen], d[chosen]
    # drop points far from the running median distance (stray edges inside the band)
    if len(pts) > 10:
        k = 7
        padded = np.r_[dist[-k:], dist, dist[:k]]
        windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * k + 1)
        median = np.median(windows, axis=1)
        pts = pts[np.abs(dist - median) < 2.0]
    return pts


def component_outline(image: np.ndarray, predicted_px: np.ndarray, sigma: float = 1.0, tolerance_px: float = 8.0,
                      polarity: str = "dark", search_px: int = 60) -> np.ndarray:
    """Ordered, closed, sub-pixel outline (K, 2) of the component predicted at ``predicted_px``."""
    predicted = np.asarray(predicted_px, dtype=float)
    if len(predicted) < 4:
        raise ValueError("the predicted outline has fewer than 4 points")
    _, gx, gy = smoothed_gradients(image, sigma)
    margin = search_px + tolerance_px
    lo, hi = predicted.min(0) - margin, predicted.max(0) + margin
    edges = canny_edges(image, sigma, roi=(int(lo[0]), int(lo[1]), int(np.ceil(hi[0])), int(np.ceil(hi[1]))))
    if not edges.any():
        raise ValueError("the image has no edges")
    shifted = predicted + best_shift(edges, predicted, search_px)
    vs, us = np.nonzero(edges)
    pixels = select_outline([np.column_stack([us, vs]).astype(float)], shifted, tolerance_px, 0.0)
    refined, grad = subpixel_edges(gx, gy, pixels)
    poly = _dense_polyline(shifted)
    _, idx = cKDTree(poly).query(refined)
    outward = _outward_normals(poly)[idx]
    strength = np.linalg.norm(grad, axis=1)
    if polarity == "dark":  # intensity rises outwards across the component's edge
        good = np.einsum("ij,ij->i", grad, outward) > 0.5 * strength
        refined, strength = refined[good], strength[good]
    outline = order_along(refined, strength, shifted)
    if len(outline) < 4:
        raise ValueError("too few edge points along the predicted outline")
    return outline


def outline_from_mask(mask: np.ndarray) -> np.ndarray:
    """Ordered outer boundary (K, 2) of the largest region of a binary mask."""
    contours, _ = cv2.findContours(np.asarray(mask, dtype=np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        raise ValueError("the mask is empty")
    return max(contours, key=cv2.contourArea)[:, 0, :].astype(float)
