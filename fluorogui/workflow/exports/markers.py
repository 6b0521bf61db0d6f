"""The anatomical markers of the marker files (C3D, ``.trc``): per component, the world
position (mm) of its anatomical frame's origin and of the points ``MARKER_AXIS_MM`` along
its x, y and z axes (``<component>_origin``, ``_x``, ``_y``, ``_z``)."""
from __future__ import annotations

import numpy as np

from fluorogui.core.projection.pose import pose_to_matrix
from fluorogui.workflow.exports.tables import in_motion_files, motion_components

MARKER_AXIS_MM = 10.0
MARKER_POINTS = ("origin", "x", "y", "z")


def marker_labels(components) -> list[str]:
    return [f"{c}_{point}" for c in components for point in MARKER_POINTS]


def anatomical_markers(pose, anatomical_frame) -> np.ndarray:
    """World positions (4 × 3, mm) of the anatomical origin and of the points
    ``MARKER_AXIS_MM`` along its x, y and z axes, for a model pose and its anatomical frame
    (anatomical → model)."""
    placed = pose_to_matrix(pose) @ np.asarray(anatomical_frame, dtype=float)
    origin = placed[:3, 3]
    return np.vstack([origin, *(origin + MARKER_AXIS_MM * placed[:3, k] for k in range(3))])


def marker_table(session, include_unreviewed: bool = False) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Labels, points (frames × markers × 3, mm; NaN where left out) and validity
    (frames × markers) of every frame."""
    components = motion_components(session)
    frames_of = {c: session.anatomical_frame(c) for c in components}
    labels = marker_labels(components)
    points = np.full((len(session.frames), len(labels), 3), np.nan)
    for i, frame in enumerate(session.frames):
        for k, c in enumerate(components):
            record = session.project.poses.get((frame, c))
            if in_motion_files(record, include_unreviewed):
                points[i, 4 * k:4 * k + 4] = anatomical_markers(record.pose, frames_of[c])
    return labels, points, np.all(np.isfinite(points), axis=2)


def marker_descriptions(labels: list[str]) -> list[str]:
    """What each marker is, in words (the C3D's POINT:DESCRIPTIONS)."""
    words = {"origin": "anatomical origin", "x": f"{MARKER_AXIS_MM:g} mm along the anatomical x axis (right)",
             "y": f"{MARKER_AXIS_MM:g} mm along the anatomical y axis (anterior)",
             "z": f"{MARKER_AXIS_MM:g} mm along the anatomical z axis (proximal)"}
    return [f"{label.split('_')[0]} component: {words[label.split('_', 1)[1]]}, world mm" for label in labels]
