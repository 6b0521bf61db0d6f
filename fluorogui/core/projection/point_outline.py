"""The paper's outline of a projected point cloud (Fig. 4).

Projected points are compartmentalised into a square grid; the boundary cells of the
occupied region are followed in order (OpenCV's border following on the occupancy
grid, the same left-looking contour following as the paper); in every boundary cell
the point furthest towards the outside is kept. The result is an ordered outline
that lies inside the true silhouette by up to about half the point spacing — the
known weakness the exact mesh silhouette (``silhouette.py``) removes.
"""
from __future__ import annotations

import cv2
import numpy as np


def point_spacing_px(n_points: int, surface_area_mm2: float, px_per_mm: float) -> float:
    """Typical spacing of an even surface cloud, in pixels, for choosing the grid."""
    return float(np.sqrt(surface_area_mm2 / max(n_points, 1)) * px_per_mm)


def grid_outline(points_px: np.ndarray, cell_px: float) -> np.ndarray:
    """Ordered outline points (K, 2) of a projected cloud on a grid of ``cell_px`` cells."""
    pts = np.asarray(points_px, dtype=float)
    origin = pts.min(0) - 2 * cell_px
    cells = np.floor((pts - origin) / cell_px).astype(np.int64)
    shape = cells.max(0) + 3
    occ = np.zeros((shape[1], shape[0]), np.uint8)
    occ[cells[:, 1], cells[:, 0]] = 1
    contours, _ = cv2.findContours(occ, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    border = max(contours, key=len)[:, 0, :].astype(np.int64)  # (B, 2) as (col, row)
    if len(border) < 3:
        return pts[:0]

    # outward normal of each boundary cell from its neighbours along the contour
    tangent = np.roll(border, -1, axis=0) - np.roll(border, 1, axis=0)
    signed_area = 0.5 * np.sum(border[:, 0] * np.roll(border[:, 1], -1) - np.roll(border[:, 0], -1) * border[:, 1])
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]]).astype(float)
    if signed_area < 0:
        normal = -normal

    width = shape[0]
    border_key = border[:, 1] * width + border[:, 0]
    uniq, first = np.unique(border_key, return_index=True)
    cell_normal = np.zeros((len(uniq), 2))
    np.add.at(cell_normal, np.searchsorted(uniq, border_key), normal)

    key = cells[:, 1] * width + cells[:, 0]
    slot = np.searchsorted(uniq, key)
    slot = np.clip(slot, 0, len(uniq) - 1)
    on_border = uniq[slot] == key
    idx = np.flatnonzero(on_border)
    score = np.einsum("ij,ij->i", pts[idx], cell_normal[slot[idx]])
    order = np.lexsort((-score, slot[idx]))
    pick = np.r_[True, slot[idx][order][1:] != slot[idx][order][:-1]]
    chosen = idx[order][pick]
    chosen_slot = slot[chosen]
    # back into contour order
    seq = np.argsort(first[chosen_slot], kind="stable")
    return pts[chosen[seq]]
