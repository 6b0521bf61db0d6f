"""Where a component went since the frame it was last matched in, from the images alone.

Across a jump of several frames a motion prediction can miss by tens of millimetres (the
real sequence's 10-20 frame jumps: 5-53 mm, the whole knee moves in the field), more than
a search near it covers. The image does better: the patch of the earlier frame under the
component's projection is found again in the new frame (normalised cross-correlation
under the projection's mask, ``cv2.matchTemplate``) in each view, and the centroid's
image point, moved by those shifts, triangulates to where the component now is. A pose
that has turned changes the patch less than a search's range (the real jumps: centroids
0.5-4.1 mm from the matched ones). Where the two views' shifts do not meet in one point
(another dark object took the match in one of them) there is no answer.
"""
from __future__ import annotations

from typing import Sequence

import cv2
import numpy as np

from fluorogui.core.matching.problem import _to_pose, _to_state
from fluorogui.core.projection.geometry import View, triangulate
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.projection.silhouette import projected_region

#: how far a patch is looked for, as a share of the image's width, either way
REACH = 0.3
#: the images are compared at about this width (px): enough for a start a search refines
WORK_WIDTH = 256
#: the two views' rays through the moved centroid must pass closer than this (mm)
MAX_MISS_MM = 10.0
#: and each view's correlation must reach this
MIN_CORRELATION = 0.5
#: the mask around the projection (px at full resolution): the outline's edge is in the patch
EDGE_MARGIN_PX = 6


def image_shift(before: np.ndarray, after: np.ndarray, region: np.ndarray,
                reach: float = REACH) -> tuple[np.ndarray, float] | None:
    """Where the patch of ``before`` under ``region`` (a boolean image) lies in ``after``:
    the shift (u, v) in pixels and the correlation there; None for an empty region."""
    if not region.any():
        return None
    h, w = before.shape[:2]
    scale = min(1.0, WORK_WIDTH / max(h, w))
    # the region grown by a square of EDGE_MARGIN_PX: its box is the region's, that much wider
    # (within the image), and it is grown only there (the same pixels; looking for them in
    # the whole grown image took 4 ms of each call)
    left, top, width, height = cv2.boundingRect(np.ascontiguousarray(region, dtype=bool).view(np.uint8))
    y0, y1 = max(top - EDGE_MARGIN_PX, 0), min(top + height + EDGE_MARGIN_PX, region.shape[0])
    x0, x1 = max(left - EDGE_MARGIN_PX, 0), min(left + width + EDGE_MARGIN_PX, region.shape[1])
    grown = cv2.dilate(region[y0:y1, x0:x1].astype(np.uint8), np.ones((2 * EDGE_MARGIN_PX + 1,) * 2, np.uint8))
    r = int(reach * w)
    Y0, Y1, X0, X1 = max(y0 - r, 0), min(y1 + r, h), max(x0 - r, 0), min(x1 + r, w)

    def small(a):
        return cv2.resize(np.asarray(a, np.float32), None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)

    patch, mask, window = small(before[y0:y1, x0:x1]), small(grown), small(after[Y0:Y1, X0:X1])
    if min(patch.shape) < 3 or patch.shape[0] > window.shape[0] or patch.shape[1] > window.shape[1]:
        return None
    score = cv2.matchTemplate(window, patch, cv2.TM_CCOEFF_NORMED, mask=(mask > 0.5).astype(np.float32))
    score[~np.isfinite(score)] = -1.0
    _, best, _, (u, v) = cv2.minMaxLoc(score)
    return np.array([u / scale + X0 - x0, v / scale + Y0 - y0]), float(best)


def relocated_centroid(before: Sequence[np.ndarray], after: Sequence[np.ndarray], views: Sequence[View],
                       mesh: PreparedMesh, *, pose) -> np.ndarray | None:
    """The world centroid of ``mesh`` in the images ``after``, from where it was at ``pose``
    in the images ``before`` (two views); None when a view lost it or the views disagree."""
    if len(views) != 2:
        return None
    pose = np.asarray(pose, float)
    R, centroid = _to_state(pose, mesh.centroid)
    moved = []
    for view, a, b in zip(views, before, after):
        found = image_shift(a, b, projected_region(view, [(mesh, R, pose[:3])], 0))
        if found is None or found[1] < MIN_CORRELATION:
            return None
        moved.append(view.project(centroid[None])[0] + found[0])
    point, miss = triangulate(views, [p[None] for p in moved])
    return point if miss <= MAX_MISS_MM else None


def with_centroid(pose, mesh: PreparedMesh, centroid: np.ndarray) -> np.ndarray:
    """``pose`` moved (not turned) so that the mesh's centroid lies at ``centroid``."""
    R = _to_state(np.asarray(pose, float), mesh.centroid)[0]
    return _to_pose(R, np.asarray(centroid, float), mesh.centroid)


__all__ = ["image_shift", "relocated_centroid", "with_centroid"]
