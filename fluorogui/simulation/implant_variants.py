"""Procedural variants of an implant mesh for validation, so overfitting to one design shows.

Meshes are in the component frame of ``simulation.phantoms`` and the shipped models: x
mediolateral, y anteroposterior (+y anterior), z proximodistal (+z proximal).

* ``ps_box``: a posterior-stabilised femoral component - a closed box (the housing of
  the cam and post) added between the condyles, rising proximally into the bone side, so
  the lateral outline changes. The box is a separate closed shell; the X-ray model sums
  path lengths over shells, the silhouette is their union's.
* ``mirrored_half``: a symmetric tray - one half of the mesh (cut at the plane through
  its bounding-box centre) mirrored onto the other, stitched along the cut: closed where
  the input is closed.
"""
from __future__ import annotations

import numpy as np

#: the box's extent as fractions of the component's bounding box: half width (x),
#: anteroposterior range (y, from posterior) and proximodistal range (z, from distal)
PS_BOX_HALF_WIDTH = 0.10
PS_BOX_AP = (0.25, 0.60)
PS_BOX_PD = (0.15, 0.55)


def box_mesh(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """A closed axis-aligned box from corner ``lo`` to ``hi``, 12 triangles facing outwards."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    corners = np.array([[(hi if (k >> a) & 1 else lo)[a] for a in range(3)] for k in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return corners, np.array(faces, dtype=np.int64)


def ps_box_bounds(vertices) -> tuple[np.ndarray, np.ndarray]:
    """Corners of the posterior-stabilised box for a femoral component's vertices."""
    v = np.asarray(vertices, dtype=float)
    lo, hi = v.min(0), v.max(0)
    size, mid = hi - lo, (lo + hi) / 2.0
    half = PS_BOX_HALF_WIDTH * size[0]
    return (np.array([mid[0] - half, lo[1] + PS_BOX_AP[0] * size[1], lo[2] + PS_BOX_PD[0] * size[2]]),
            np.array([mid[0] + half, lo[1] + PS_BOX_AP[1] * size[1], lo[2] + PS_BOX_PD[1] * size[2]]))


def ps_box(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """The femoral mesh plus a closed intercondylar box (see the module docstring)."""
    v, f = np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64)
    bv, bf = box_mesh(*ps_box_bounds(v))
    return np.vstack([v, bv]), np.vstack([f, bf + len(v)])


def mirrored_half(vertices, faces, axis: int, keep_positive: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The mesh's half on one side of the plane ``axis = centre`` (centre of the bounding
    box) with its mirror image on the other side, merged along the cut."""
    import pyvista as pv

    v, f = np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64)
    centre = (v.min(0) + v.max(0)) / 2.0
    v = v - centre  # cut at zero, so the cut's vertices mirror onto themselves exactly
    mesh = pv.PolyData(v, np.column_stack([np.full(len(f), 3), f]).ravel())
    normal = np.eye(3)[axis]
    half = mesh.clip(normal=normal, origin=(0.0, 0.0, 0.0), invert=not keep_positive).triangulate().clean()
    p = np.asarray(half.points, dtype=float).copy()
    p[np.abs(p[:, axis]) < 1e-6, axis] = 0.0
    tri = half.faces.reshape(-1, 4)[:, 1:]
    q = p.copy()
    q[:, axis] *= -1.0
    both = pv.PolyData(np.vstack([p, q]), np.column_stack([np.full(2 * len(tri), 3),
                                                            np.vstack([tri, tri[:, ::-1] + len(p)])]).ravel())
    merged = both.clean(tolerance=1e-9, absolute=True)
    return np.asarray(merged.points, dtype=float) + centre, merged.faces.reshape(-1, 4)[:, 1:].astype(np.int64)
