"""From images to a pose without hand-made outlines: segment near a pose, match, repeat.

The outline of a component is segmented along the projection of a rough pose
(``edges.component_outline``). When that pose is several degrees off, parts of the true
edge fall outside the search band and the spline bridges them with a chord; matching
once and segmenting again along the matched pose removes that, as a user reviewing the
outline would. Where part of the outline is too faint for Canny's default thresholds
(a tibial keel in bone next to the tray and the femoral component), component_outline
searches the uncovered runs again with lower thresholds instead of bridging them.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .edges import component_outline
from .geometry import View
from .matching import MatchProblem, MatchResult, MatchSettings, match
from .mesh import PreparedMesh
from .pose import rotation_matrix
from .silhouette import mesh_silhouette
from .spline import OutlineSpline


def predicted_outline(mesh: PreparedMesh, pose, view: View, spacing_px: float = 2.0) -> np.ndarray:
    """The projected model outline at ``pose`` (pixels), for choosing image edges."""
    pose = np.asarray(pose, dtype=float)
    return mesh_silhouette(mesh, rotation_matrix(*pose[3:]), pose[:3], view).resample(spacing_px=spacing_px).points_px


def segment_outlines(images: Sequence[np.ndarray], views: Sequence[View], mesh: PreparedMesh, pose) -> list[np.ndarray]:
    """Ordered sub-pixel outline of the component in every image, chosen along ``pose``."""
    return [component_outline(image, predicted_outline(mesh, pose, view)) for image, view in zip(images, views)]


def splines_from_images(images, views, mesh, pose) -> list[OutlineSpline]:
    return [OutlineSpline.fit(o) for o in segment_outlines(images, views, mesh, pose)]


def match_images(images, views, mesh: PreparedMesh, start, settings: MatchSettings | None = None,
                 passes: int = 2, progress=None, cancel=None,
                 splines: list[OutlineSpline] | None = None) -> tuple[MatchResult, list[OutlineSpline]]:
    """Segment along the start pose and match; then ``passes - 1`` times segment along the
    result and match again from it. ``splines``, when given, serve as the first pass's
    outlines. Returns the last result and its splines."""
    settings = settings or MatchSettings()
    pose = np.asarray(start, dtype=float)
    total_calls, total_seconds = 0, 0.0
    result = None
    for k in range(max(1, passes)):
        if k > 0 or splines is None:
            splines = splines_from_images(images, views, mesh, pose)
        result = match(MatchProblem(mesh, views, splines), pose, settings, progress, cancel)
        total_calls += result.calls
        total_seconds += result.seconds
        pose = result.pose
        if result.cancelled:
            break
    result.calls, result.seconds = total_calls, total_seconds
    return result, splines
