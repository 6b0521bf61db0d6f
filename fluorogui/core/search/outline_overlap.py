"""Find's overlap check: the IoU of a component's silhouette with the region inside its
image outline, on what the outline actually traced.

The image outline is closed across stretches where no edge was found (its ``gaps``: a
faint stem, a keel lost in bone) by spline chords that follow no edge; a chord can cut
across the stem or bulge beside it, and the region it encloses there says nothing about
where the component is. Such a region (a connected piece of the silhouette's and the
outline region's difference that a chord bounds) is left out of the IoU, as another
component's projection is, but only when the silhouette along it lies on image edges
(``GAP_EDGE_SUPPORT`` of its points within 1.5 px of a low-threshold Canny edge, the
tracking checks' edge support): there the outline missed an edge the image has. Where the
silhouette runs off the edges (a wrong pose) the region counts as before. On the real
frames 200 and 220 (issue 48) the tray's IoU in view 1 went from 0.93 / 0.69 to 0.98 /
0.99 at the pose tracking matches; wrong candidates at frame 140 stay where they were
(their silhouettes beside the chords lie 36-49 % on edges).
"""
from __future__ import annotations

import cv2
import numpy as np

from fluorogui.core.matching.quality import edge_support
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.pose import rotation_matrix
from fluorogui.core.search import shape_search as ss

#: share of the silhouette beside a chord's region that must lie on image edges for the
#: region to be left out (right poses on the real frames: 0.94-1.0; wrong ones 0.36-0.49)
GAP_EDGE_SUPPORT = 0.85
#: fewer silhouette points (half resolution px of outline) beside a region than this: not judged, it counts
MIN_BORDER_POINTS = 8


def _to_half(points: np.ndarray) -> np.ndarray:
    return points * 0.5 - 0.25


def _chords(spline, shape) -> np.ndarray:
    """Where the outline's chords across gaps run (half resolution, 3 px wide)."""
    out = np.zeros(shape, np.uint8)
    for a, b in spline.gaps:
        pts = spline.evaluate(np.linspace(a, b, max(2, int(b - a) + 1)))
        cv2.polylines(out, [np.round(_to_half(pts)).astype(np.int32)], False, 1, 3)
    return out > 0


def untraced(a: np.ndarray, b: np.ndarray, free: np.ndarray, spline, silhouette: np.ndarray,
             image: np.ndarray | None) -> np.ndarray:
    """The pixels (half resolution) of the silhouette ``a`` / outline region ``b``
    difference that a chord across a gap bounds and whose silhouette lies on image edges."""
    left_out = np.zeros(a.shape, bool)
    if image is None or not len(spline.gaps):
        return left_out
    chords = _chords(spline, a.shape)
    diff = ((a ^ b) & free).astype(np.uint8)
    n, labels = cv2.connectedComponents(diff, connectivity=8)
    touched = np.unique(labels[chords & (diff > 0)])
    if not len(touched[touched > 0]):
        return left_out
    h, w = a.shape
    at = np.clip(np.round(_to_half(silhouette)).astype(int), 0, [w - 1, h - 1])
    for label in touched[touched > 0]:
        region = labels == label
        beside = cv2.dilate(region.astype(np.uint8), np.ones((5, 5), np.uint8))[at[:, 1], at[:, 0]] > 0
        if beside.sum() >= MIN_BORDER_POINTS and edge_support(image, silhouette[beside]) >= GAP_EDGE_SUPPORT:
            left_out |= region
    return left_out


def outline_iou(mesh, pose, view: View, spline, *, shape, hidden: np.ndarray | None = None,
                image: np.ndarray | None = None) -> float:
    """IoU at half resolution of the silhouette at ``pose`` and the region inside ``spline``,
    on the part of the image ``hidden`` (another component's projection) leaves free and
    without the regions the outline's chords bound where the silhouette lies on the edges
    of ``image`` (not looked for without it)."""
    h, w = shape[0] // 2, shape[1] // 2
    a = np.zeros((h, w), np.uint8)
    b = np.zeros((h, w), np.uint8)
    R = rotation_matrix(*pose[3:])
    sil = ss.outline(mesh, R, R @ mesh.centroid + pose[:3], view, spacing_px=1.0, nearest=False)[0]
    ring = spline.sample(max(64, int(spline.length_px)))
    for canvas, pts in ((a, sil), (b, ring)):
        cv2.fillPoly(canvas, [np.round(_to_half(pts) * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    free = np.ones((h, w), bool)
    if hidden is not None:
        free = cv2.resize(np.asarray(hidden, np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) == 0
    a, b = a > 0, b > 0
    free &= ~untraced(a, b, free, spline, sil, image)
    a, b = a & free, b & free
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 0.0
