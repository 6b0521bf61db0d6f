"""Default anatomical frames of knee-implant components, from the implant's own geometry.

A frame is a 4×4 matrix mapping anatomical to model coordinates: x to the subject's right
(for both knees), y anterior, z proximal, origin at the joint centre.

* **Femoral component.** Its articular surface wraps around the mediolateral axis, so
  the area-weighted scatter of the surface normals is smallest along it (flat side walls,
  whose normals lie along the axis, are left out once a first estimate is known). The
  proximal direction is the normal of the distal bone cut (the flat inner face whose
  normal points into the U of the component, away from its material); the anterior side
  is the one the flange reaches highest on. The origin is the centre of the circle
  fitted to the distal and posterior condylar surface in the sagittal plane (the flexion
  facet centre), midway between the component's medial and lateral ends.
* **Tibial component.** The long axis is the normal of the tray's largest flat area; the
  proximal side is the one the material crowds at (the stem or keel is the long, thin
  tail). The mediolateral axis is the tray's wider in-plane direction; the posterior
  border is the straight, wide one (the anterior border is round), so the tray is wider
  near its posterior end than near its anterior end. The origin is the centre of the tray's top.

Either may be wrong for an unusual design; the app and the command line let the user
replace them (``fluorogui.core.knee.kinematics.check_frame`` checks a replacement).
"""
from __future__ import annotations

import numpy as np

from fluorogui.core.knee.kinematics import KinematicsError


def _faces(vertices: np.ndarray, faces: np.ndarray):
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    cross = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    keep = area > 1e-12
    normals = cross[keep] / (2.0 * area[keep, None])
    return normals, area[keep], ((a + b + c) / 3.0)[keep]


def _check(vertices, faces) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) < 4:
        raise KinematicsError("the mesh needs at least 4 vertices for an anatomical frame")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) < 4:
        raise KinematicsError("the mesh needs at least 4 triangles for an anatomical frame")
    normals, area, centres = _faces(vertices, faces)
    if area.sum() <= 0:
        raise KinematicsError("the mesh has no area")
    return vertices, normals, area, centres


def _frame(x, y, z, origin) -> np.ndarray:
    out = np.eye(4)
    out[:3, 0], out[:3, 1], out[:3, 2], out[:3, 3] = x, y, z, origin
    return out


def _unit(v) -> np.ndarray:
    return np.asarray(v, dtype=float) / float(np.linalg.norm(v))


def _dominant_plane_normal(normals, area, candidates: int = 400, cos_tol: float = 0.999) -> np.ndarray:
    """The normal direction (up to sign) shared by the largest flat area."""
    best, best_area = None, -1.0
    for idx in np.argsort(-area)[:candidates]:
        d = normals[idx]
        share = float(area[np.abs(normals @ d) > cos_tol].sum())
        if share > best_area:
            best, best_area = d, share
    flat = np.abs(normals @ best) > cos_tol
    signs = np.sign(normals[flat] @ best)
    return _unit(((normals[flat] * signs[:, None]) * area[flat, None]).sum(axis=0))


def _raster(points_2d: np.ndarray, triangles_2d: np.ndarray, step: float = 0.25):
    """The union of 2-D triangles as a mask (rows along the second coordinate), its grid
    origin and step."""
    import cv2

    low = points_2d.min(axis=0) - 1.0
    size = np.ceil((points_2d.max(axis=0) + 1.0 - low) / step).astype(int) + 1
    mask = np.zeros((size[1], size[0]), np.uint8)
    pix = np.round((triangles_2d - low) / step).astype(np.int32)
    cv2.fillPoly(mask, list(pix), 1)
    if not mask.any():
        raise KinematicsError("the component's outline is empty")
    return mask.astype(bool), low, step


def _area_centroid(mask, low, step):
    """Area centroid and bounding-box centre of a mask, in the mask's 2-D coordinates."""
    rows, cols = np.nonzero(mask)
    centroid = low + step * np.array([cols.mean(), rows.mean()])
    box_centre = low + step * np.array([(cols.min() + cols.max()) / 2, (rows.min() + rows.max()) / 2])
    return centroid, box_centre


def default_tibial_frame(vertices, faces) -> np.ndarray:
    """The tibial component's anatomical frame (anatomical → model), from its shape."""
    vertices, normals, area, centres = _check(vertices, faces)
    z = _dominant_plane_normal(normals, area)
    heights = vertices @ z
    if np.median(heights) < 0.5 * (heights.min() + heights.max()):
        z, heights = -z, -heights  # the stem is the thin tail: proximal is where the material is
    top = heights.max()
    plate = heights > top - 0.35 * (top - heights.min())  # the tray, not the stem
    plate_points = vertices[plate] - vertices[plate].mean(axis=0)
    flat = plate_points - np.outer(plate_points @ z, z)
    _, _, vt = np.linalg.svd(flat, full_matrices=False)
    ml = _unit(vt[0] - (vt[0] @ z) * z)
    ap = np.cross(z, ml)
    faces = np.asarray(faces, dtype=np.int64)
    tray_faces = faces[np.all(plate[faces], axis=1)]
    coords = np.column_stack([vertices @ ml, vertices @ ap])
    mask, low, step = _raster(coords, coords[tray_faces])
    _, box_centre = _area_centroid(mask, low, step)
    origin = box_centre[0] * ml + box_centre[1] * ap + top * z
    rows = np.flatnonzero(mask.any(axis=1))
    inset = max(1, int(0.08 * (rows[-1] - rows[0])))
    width_low, width_high = (int(mask[r].sum()) for r in (rows[0] + inset, rows[-1] - inset))
    if width_high > width_low:  # the posterior border is the wide, straight one (the anterior is round)
        ap = -ap
    y = ap
    x = np.cross(y, z)
    return _frame(x, y, z, origin)


def _circle_fit(points_2d: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Least-squares (Kasa) circle centre of weighted 2-D points."""
    A = np.column_stack([2 * points_2d, np.ones(len(points_2d))])
    b = (points_2d ** 2).sum(axis=1)
    w = np.sqrt(weights)
    solution, *_ = np.linalg.lstsq(A * w[:, None], b * w, rcond=None)
    return solution[:2]


def default_femoral_frame(vertices, faces) -> np.ndarray:
    """The femoral component's anatomical frame (anatomical → model), from its shape."""
    vertices, normals, area, centres = _check(vertices, faces)
    keep = np.ones(len(area), bool)
    for _ in range(3):  # leave out the flat side walls, whose normals lie along the axis
        scatter = (normals[keep] * area[keep, None]).T @ normals[keep]
        axis = np.linalg.eigh(scatter)[1][:, 0]
        keep = np.abs(normals @ axis) < 0.5
    ml = _unit(axis)
    # the U of the component opens proximally: its material lies distal of the hull's middle
    sagittal_u = _unit(np.cross(ml, [1.0, 0, 0]) if abs(ml[0]) < 0.9 else np.cross(ml, [0, 1.0, 0]))
    sagittal_v = np.cross(ml, sagittal_u)
    coords = np.column_stack([vertices @ sagittal_u, vertices @ sagittal_v])
    faces = np.asarray(faces, dtype=np.int64)
    material, box_centre = _area_centroid(*_raster(coords, coords[faces]))
    guess = _unit(box_centre - material)  # towards the open side: roughly proximal
    guess3 = _unit(guess[0] * sagittal_u + guess[1] * sagittal_v)
    # refine with the distal cut: flat faces facing into the U, close to the guess
    side = np.abs(normals @ ml) < 0.2
    candidates = side & (normals @ guess3 > np.cos(np.radians(35)))
    z = guess3
    if candidates.any():  # every candidate faces along the guess, so the cut's normal does too
        cut = _dominant_plane_normal(normals[candidates], area[candidates], cos_tol=0.998)
        z = _unit(cut - (cut @ ml) * ml)
    ap = np.cross(z, ml)
    heights = vertices @ z
    high = heights > heights.max() - 0.15 * (heights.max() - heights.min())
    if np.mean(vertices[high] @ ap) < np.mean(vertices @ ap):  # the flange is the highest part
        ap = -ap
    y = ap
    x = np.cross(y, z)
    # flexion facet centre: circle through the distal and posterior outer surface
    outward = (normals @ -z > 0.3) | (normals @ -y > 0.3)
    outer = outward & (np.abs(normals @ ml) < 0.5)
    lower = centres @ z < np.percentile(heights, 60)
    pick = outer & lower
    if pick.sum() < 10:
        pick = outer
    pts = np.column_stack([centres[pick] @ y, centres[pick] @ z])
    centre_yz = _circle_fit(pts, area[pick])
    ml_values = vertices @ x
    origin = 0.5 * (ml_values.min() + ml_values.max()) * x + centre_yz[0] * y + centre_yz[1] * z
    return _frame(x, y, z, origin)


def default_frame(component: str, vertices, faces) -> np.ndarray:
    """The default anatomical frame of a ``femoral`` or ``tibial`` component."""
    if component == "femoral":
        return default_femoral_frame(vertices, faces)
    if component == "tibial":
        return default_tibial_frame(vertices, faces)
    raise KinematicsError(f"no anatomical frame is defined for a {component!r} component")
