"""Other edges beside a component's outline: where the rim refinement cannot be trusted.

The rim refinement (``core.rim``) explains the pixels around each outline point by the
metal's rim profile over a background that changes linearly across the edge. Where
another edge runs close by - a bone's cortex along a femoral flange or under a tray, the
leg's skin line, another component's rim - the background has a step, and the fit moves
the point by a few tenths of a pixel along the whole stretch, too little and too evenly
to be told from the rim itself. On the independent X-ray model, the bone shaft's edges
within about 7 px of the outline (the fit's window is 4 px either side, and the moves
are smoothed along the outline) moved the 15 % smaller femur 0.058 deg at 60 deg of
flexion without noise (0.008 deg with the bone left out of the image).

``near_other_edges`` finds those outline points from the image: Canny edges at low
thresholds around the outline, without the component's own edge (inside the outline or
within ``OWN_EDGE_PX`` of it) and without the pixels under an exclusion mask. Where a bone
edge runs right along the component's edge, Canny sees one edge there; but the bone's
edge goes on beyond that stretch, and a straight run of edge pixels is extended by
``EXTEND_PX`` along its own direction to find it. The refinement leaves those points out
of the outline, and the spline bridges them as gaps the matcher does not measure.
"""
from __future__ import annotations

import cv2
import numpy as np

from .edges import canny_edges

#: outline points within this distance (px) of another edge are near it
NEAR_PX = 7.0
#: Canny pixels inside the outline or within this distance (px) of it are the component's own
OWN_EDGE_PX = 1.5
#: Canny thresholds (fractions of the strongest gradients around the outline): low enough
#: for a bone's cortex beside cobalt-chrome (about a tenth of the metal's contrast)
LOW, HIGH = 0.04, 0.12
#: straight runs of edge pixels (at least ``MIN_RUN_PX`` of them) are extended by this (px)
#: at both ends
EXTEND_PX, MIN_RUN_PX = 40.0, 12
#: a run is straight when its pixels' spread across its direction is below this (px^2),
#: and below this fraction of the spread along it
STRAIGHT_VAR_PX2, STRAIGHT_RATIO = 1.0, 0.05


def near_other_edges(image: np.ndarray, outline_px: np.ndarray, exclude: np.ndarray | None = None,
                     near_px: float = NEAR_PX) -> np.ndarray:
    """True for the points of a closed outline (K, 2; u, v px) within ``near_px`` of an
    edge in ``image`` that is not the component's own; edges under ``exclude`` (a boolean
    image) do not count."""
    points = np.asarray(outline_px, dtype=float).reshape(-1, 2)
    if len(points) < 3:
        return np.zeros(len(points), dtype=bool)
    image = np.asarray(image, dtype=float)
    h, w = image.shape[:2]
    margin = near_px + EXTEND_PX / 4 + 8
    u0, v0 = (max(int(np.floor(x - margin)), 0) for x in points.min(0))
    u1, v1 = min(int(np.ceil(points[:, 0].max() + margin)), w), min(int(np.ceil(points[:, 1].max() + margin)), h)
    if u1 - u0 < 8 or v1 - v0 < 8:
        return np.zeros(len(points), dtype=bool)
    edges = canny_edges(image[v0:v1, u0:u1], LOW, HIGH, 1.0)
    local = points - [u0, v0]
    polygon = [np.round(local * 16).astype(np.int32)]  # 4 fractional bits
    inside = np.zeros(edges.shape, np.uint8)
    cv2.fillPoly(inside, polygon, 1, shift=4)
    line = np.ones(edges.shape, np.uint8)
    cv2.polylines(line, polygon, True, 0, 1, shift=4)
    from_outline = cv2.distanceTransform(line, cv2.DIST_L2, 5)
    other = edges & (inside == 0) & (from_outline > OWN_EDGE_PX)
    if exclude is not None:
        other &= ~np.asarray(exclude, dtype=bool)[v0:v1, u0:u1]
    if not other.any():
        return np.zeros(len(points), dtype=bool)
    other |= _extended_runs(other)
    distance = cv2.distanceTransform((~other).astype(np.uint8), cv2.DIST_L2, 5)
    cols = np.clip(np.round(local[:, 0]).astype(int), 0, edges.shape[1] - 1)
    rows = np.clip(np.round(local[:, 1]).astype(int), 0, edges.shape[0] - 1)
    return distance[rows, cols] < near_px


def _extended_runs(edges: np.ndarray) -> np.ndarray:
    """Lines (a boolean image) extending each straight run of connected edge pixels by
    ``EXTEND_PX`` at both ends along its own direction."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(edges.astype(np.uint8), connectivity=8)
    lines = np.zeros(edges.shape, np.uint8)
    for i in range(1, count):
        if stats[i, cv2.CC_STAT_AREA] < MIN_RUN_PX:
            continue
        rows, cols = np.nonzero(labels == i)
        xy = np.column_stack([cols, rows]).astype(float)
        centre = xy.mean(0)
        spread, axes = np.linalg.eigh(np.cov((xy - centre).T))
        if spread[0] > STRAIGHT_VAR_PX2 or spread[0] > STRAIGHT_RATIO * spread[1]:
            continue  # not straight: where it would go on is not known
        direction = axes[:, 1]
        along = (xy - centre) @ direction
        a = centre + (along.min() - EXTEND_PX) * direction
        b = centre + (along.max() + EXTEND_PX) * direction
        cv2.line(lines, tuple(int(x) for x in np.round(a)), tuple(int(x) for x in np.round(b)), 1, 1)
    return lines > 0
