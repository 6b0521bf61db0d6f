"""Image outlines made without the matcher's code, for checking its uncertainty.

``bent_ellipsoid`` is a convex, slightly bent tri-axial ellipsoid mesh (no mirror
symmetry, so all six pose variables show in its outline); ``noisy_hull_outline`` projects
its vertices with the pinhole formula written out here and takes the convex hull of the
projected points (exactly the silhouette of a convex mesh), resampled every pixel and
displaced along its normal by Gaussian noise correlated over ``corr_px`` pixels, as edge
noise after blur is. No import from ``fluorogui``.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import ConvexHull


def bent_ellipsoid(radii=(30.0, 20.0, 12.0), bend: float = 0.15, resolution=(96, 72)):
    """(vertices, faces) of a tri-axial ellipsoid bent a little along its first axis."""
    import pyvista as pv

    s = pv.Sphere(radius=1.0, theta_resolution=resolution[0], phi_resolution=resolution[1])
    p = np.asarray(s.points) * np.asarray(radii, dtype=float)
    p[:, 0] += bend * p[:, 1] ** 2 / radii[1]
    return p, np.asarray(s.faces).reshape(-1, 4)[:, 1:]


def noisy_hull_outline(view, world_vertices, noise_px: float, corr_px: float, *, rng) -> np.ndarray:
    """Ordered outline points (K, 2) in pixels of a convex body's projection, with noise."""
    d = np.asarray(world_vertices, dtype=float) - np.asarray(view.source)
    w = d @ np.asarray(view.normal)
    fx, fy = view.distance / view.pitch[0], view.distance / view.pitch[1]
    uv = np.column_stack([view.principal_point[0] + fx * (d @ np.asarray(view.e_u)) / w,
                          view.principal_point[1] + fy * (d @ np.asarray(view.e_v)) / w])
    hull = uv[ConvexHull(uv).vertices]
    closed = np.vstack([hull, hull[:1]])
    arc = np.r_[0, np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))]
    s = np.arange(0, arc[-1], 1.0)
    pts = np.column_stack([np.interp(s, arc, closed[:, 0]), np.interp(s, arc, closed[:, 1])])
    tangent = np.roll(pts, -1, 0) - np.roll(pts, 1, 0)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]]) / np.linalg.norm(tangent, axis=1)[:, None]
    e = rng.normal(size=len(pts))
    if corr_px > 0:
        e = gaussian_filter1d(e, corr_px, mode="wrap")
    return pts + (e * noise_px / e.std())[:, None] * normal
