"""Procedural implant phantoms: a sphere, a femoral and a tibial TKA component.

A mesh is ``(vertices (N, 3) float64, faces (M, 3) int64)`` in millimetres: closed
(every edge shared by exactly two faces), triangles ordered counter-clockwise seen from
outside. The components are implant-like, not anatomical: sized like real parts and
deliberately non-symmetric so that their pose is unambiguous from two views.

Component frame (both components): x mediolateral (+x medial), y anteroposterior
(+y anterior), z proximodistal (+z proximal).
"""
from __future__ import annotations

import numpy as np

Mesh = tuple[np.ndarray, np.ndarray]


# --------------------------------------------------------------------------- helpers


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed mesh; positive when faces are oriented outwards."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _oriented_outwards(vertices: np.ndarray, faces: np.ndarray) -> Mesh:
    if signed_volume(vertices, faces) < 0:
        faces = faces[:, ::-1]
    return np.ascontiguousarray(vertices, dtype=np.float64), np.ascontiguousarray(faces, dtype=np.int64)


def _compact(vertices: np.ndarray, faces: np.ndarray) -> Mesh:
    used, inverse = np.unique(faces, return_inverse=True)
    return vertices[used], inverse.reshape(faces.shape)


def _quads_to_triangles(quads: np.ndarray) -> np.ndarray:
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def _cell_union_surface(points: np.ndarray, cells: np.ndarray) -> Mesh:
    """Boundary of a union of cells of a deformed structured grid.

    ``points`` (ni, nj, nk, 3) are the grid nodes, ``cells`` (ni-1, nj-1, nk-1) bool
    says which hexahedral cells are solid. Every cell face not shared with another solid
    cell is emitted, ordered so its normal points out of the cell in grid-index space;
    the result is closed and consistently oriented (outward if the grid map preserves
    orientation). Avoid cells that touch only along an edge (non-manifold).
    """
    ni, nj, nk = points.shape[:3]
    index = np.arange(ni * nj * nk).reshape(ni, nj, nk)
    padded = np.pad(cells, 1, constant_values=False)
    quads = []
    # Corner offsets of the face normal to each axis, ordered counter-clockwise about +axis.
    face_corners = {
        0: [(0, 0, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1)],
        1: [(0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 0, 0)],
        2: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
    }
    ci, cj, ck = np.nonzero(cells)
    for axis in range(3):
        for step in (-1, 1):
            shift = [0, 0, 0]
            shift[axis] = step
            neighbour_solid = padded[ci + 1 + shift[0], cj + 1 + shift[1], ck + 1 + shift[2]]
            sel = ~neighbour_solid
            i, j, k = ci[sel], cj[sel], ck[sel]
            base = [i, j, k]
            if step == 1:
                base[axis] = base[axis] + 1
            corners = [index[base[0] + o[0], base[1] + o[1], base[2] + o[2]] for o in face_corners[axis]]
            quad = np.stack(corners, axis=1)
            quads.append(quad if step == 1 else quad[:, ::-1])
    faces = _quads_to_triangles(np.concatenate(quads))
    return _compact(points.reshape(-1, 3), faces)


def _ring_stack_surface(rings: np.ndarray, top: np.ndarray, bottom: np.ndarray) -> Mesh:
    """Closed surface through rings (K, n, 3) of n points each, capped by two pole points."""
    n_rings, n = rings.shape[:2]
    vertices = np.concatenate([top[None], rings.reshape(-1, 3), bottom[None]])
    ring_index = 1 + np.arange(n_rings * n).reshape(n_rings, n)
    nxt = np.roll(ring_index, -1, axis=1)
    quads = np.stack([ring_index[:-1], ring_index[1:], nxt[1:], nxt[:-1]], axis=-1).reshape(-1, 4)
    top_fan = np.stack([np.zeros(n, int), ring_index[0], nxt[0]], axis=1)
    bottom_fan = np.stack(
        [np.full(n, len(vertices) - 1), nxt[-1], ring_index[-1]], axis=1
    )
    faces = np.concatenate([top_fan, _quads_to_triangles(quads), bottom_fan])
    return vertices, faces


# ---------------------------------------------------------------------------- sphere


def sphere_mesh(diameter: float = 12.70, subdivisions: int = 4) -> Mesh:
    """Icosphere centred at the origin (subdivisions=4: 2562 vertices, 5120 faces)."""
    t = (1.0 + 5.0**0.5) / 2.0
    vertices = np.array(
        [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0],
         [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=float)
    faces = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
         [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
         [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
         [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], dtype=np.int64)
    vertices /= np.linalg.norm(vertices, axis=1, keepdims=True)
    for _ in range(subdivisions):
        edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        unique_edges, edge_id = np.unique(edges, axis=0, return_inverse=True)
        edge_id = edge_id.reshape(3, -1).T + len(vertices)
        midpoints = vertices[unique_edges].mean(axis=1)
        midpoints /= np.linalg.norm(midpoints, axis=1, keepdims=True)
        vertices = np.concatenate([vertices, midpoints])
        a, b, c = faces.T
        ab, bc, ca = edge_id.T
        faces = np.concatenate([
            np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1),
            np.stack([c, ca, bc], 1), np.stack([ab, bc, ca], 1)])
    return _oriented_outwards(vertices * (diameter / 2.0), faces)


# ------------------------------------------------------------------ femoral component

#: Sagittal centre line of the femoral band: a straight anterior flange, then an arc.
_FLANGE_LENGTH = 38.0  # mm, straight anterior flange (z from +38 down to 0 at y = +26)
_ARC_RADIUS = 26.0  # mm, distal/posterior condylar arc about (y, z) = (0, 0)
_ARC_SWEEP = np.deg2rad(200.0)  # from anterior (0 deg) round the distal end to posterior


def _femoral_centre_line(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Point (y, z) and outward unit normal at arc length s along the sagittal band."""
    s = np.asarray(s, float)
    on_arc = s > _FLANGE_LENGTH
    phi = -(s - _FLANGE_LENGTH) / _ARC_RADIUS  # clockwise angle in the (y, z) plane
    y = np.where(on_arc, _ARC_RADIUS * np.cos(phi), _ARC_RADIUS)
    z = np.where(on_arc, _ARC_RADIUS * np.sin(phi), _FLANGE_LENGTH - s)
    ny = np.where(on_arc, np.cos(phi), 1.0)
    nz = np.where(on_arc, np.sin(phi), 0.0)
    return np.stack([y, z], -1), np.stack([ny, nz], -1)


def _smooth_hump(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """1 in the middle of [lo, hi], falling smoothly (elliptically) to 0 at its ends."""
    u = np.clip((2.0 * x - lo - hi) / (hi - lo), -1.0, 1.0)
    return np.sqrt(1.0 - u * u)


def femoral_component_mesh(n_mediolateral: int = 56, n_sagittal: int = 110) -> Mesh:
    """Implant-like femoral component (~64 mm ML, ~60 mm AP, ~22k triangles).

    A thick band swept along a J-shaped sagittal curve: anterior flange, distal and
    posterior condyles, with an intercondylar notch cut through the distal/posterior
    part. Asymmetries: the medial condyle is wider than the lateral, the notch is off
    centre, the flange top is slanted (lateral side higher) and the medial posterior
    condyle reaches further than the lateral.
    """
    lateral_edge, notch_lateral, notch_medial, medial_edge = -30.0, -8.0, 6.0, 34.0
    n_notch = max(4, n_mediolateral // 5)
    n_side = (n_mediolateral - n_notch) // 2
    x = np.unique(np.concatenate([
        np.linspace(lateral_edge, notch_lateral, n_side),
        np.linspace(notch_lateral, notch_medial, n_notch),
        np.linspace(notch_medial, medial_edge, n_mediolateral - n_notch - n_side + 2)]))
    ni, nj = len(x), n_sagittal

    total_length = _FLANGE_LENGTH + _ARC_RADIUS * _ARC_SWEEP
    lateral_weight = (medial_edge - x) / (medial_edge - lateral_edge)  # 1 lateral, 0 medial
    s_start = 6.0 - 6.0 * lateral_weight  # flange top: lateral side 6 mm higher
    s_end = total_length - 5.0 * lateral_weight  # medial posterior condyle reaches further
    fraction = np.linspace(0.0, 1.0, nj)
    s = s_start[:, None] + (s_end - s_start)[:, None] * fraction[None, :]  # (ni, nj)
    centre, normal = _femoral_centre_line(s)

    # Thickness across the band: two rounded condyles with a groove between them.
    # The groove is the shallow trochlea on the flange and deepens distally.
    condyles = np.maximum(
        _smooth_hump(x, lateral_edge - 3.0, notch_lateral + 4.0),
        _smooth_hump(x, notch_medial - 4.0, medial_edge + 3.0))
    flange = np.clip(0.55 + 0.45 * np.abs(x - 0.5 * (notch_lateral + notch_medial)) / 18.0, 0.55, 1.0)
    flange = np.minimum(flange, 0.35 + condyles)
    blend = np.clip((s - _FLANGE_LENGTH + 10.0) / 25.0, 0.0, 1.0)  # 0 on flange, 1 on condyles
    profile = (1.0 - blend) * flange[:, None] + blend * condyles[:, None]
    inner_offset = np.full_like(s, -3.0)  # bone-facing surface
    outer_offset = 0.8 + 4.2 * profile  # articular surface

    offsets = np.stack([inner_offset, outer_offset], axis=-1)  # (ni, nj, 2)
    points = np.empty((ni, nj, 2, 3))
    points[..., 0] = x[:, None, None]
    points[..., 1:] = centre[:, :, None, :] + offsets[..., None] * normal[:, :, None, :]

    cells = np.ones((ni - 1, nj - 1, 1), dtype=bool)
    notch_roof = _FLANGE_LENGTH + _ARC_RADIUS * np.deg2rad(70.0)  # just anterior of distal
    x_mid = 0.5 * (x[:-1] + x[1:])
    s_mid = 0.5 * (s[:-1, :-1] + s[1:, 1:])
    in_notch = (x_mid > notch_lateral) & (x_mid < notch_medial)
    cells[in_notch[:, None] & (s_mid > notch_roof), 0] = False
    return _oriented_outwards(*_cell_union_surface(points, cells))


# ------------------------------------------------------------------- tibial component


def _tray_outline_radius(theta: np.ndarray) -> np.ndarray:
    """Rounded-kidney tray outline (~70 mm ML x ~45 mm AP) as radius about its centre."""
    a, b = 35.0, 22.5
    ellipse = a * b / np.sqrt((b * np.cos(theta)) ** 2 + (a * np.sin(theta)) ** 2)
    posterior_cutout = 1.0 - 0.22 * np.exp(-(((theta + np.pi / 2 - 0.08 + np.pi) % (2 * np.pi) - np.pi) / 0.28) ** 2)
    medial_larger = 1.0 + 0.05 * np.cos(theta) + 0.03 * np.sin(theta) * np.cos(theta)
    return ellipse * posterior_cutout * medial_larger


def tibial_component_mesh(n_around: int = 144) -> Mesh:
    """Implant-like tibial component (~12k triangles): tray, keel and one fin.

    A 5 mm kidney-shaped tray with a posterior cut-out, medial side larger, and under it
    a tapered ~40 mm keel, off centre, with a single fin on the posterolateral side.
    """
    theta = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    tray = _tray_outline_radius(theta)
    keel_centre = np.array([3.0, 2.0])
    fin_angle = np.deg2rad(205.0)
    fin_shape = np.exp(-((((theta - fin_angle) + np.pi) % (2 * np.pi) - np.pi) / 0.07) ** 2)

    def keel_radius(z: float) -> np.ndarray:
        depth = -5.0 - z  # below the tray's underside
        base = 8.0 - 3.0 * np.clip(depth / 36.0, 0.0, 1.0)
        fin = 9.0 * np.clip(1.0 - depth / 20.0, 0.0, 1.0)
        return base + fin * fin_shape

    rings = []  # (centre xy, radius per theta, z)

    def add(centre, radius, z):
        rings.append((np.asarray(centre, float), radius, float(z)))

    origin = np.zeros(2)
    for scale in np.linspace(0.12, 0.96, 8):  # top surface
        add(origin, scale * tray, 0.0)
    for scale, z in [(0.985, -0.15), (1.0, -0.7), (1.0, -2.5), (1.0, -4.3), (0.985, -4.85), (0.96, -5.0)]:
        add(origin, scale * tray, z)  # rounded rim and side wall
    junction = keel_radius(-5.0) + 1.5
    for w in np.linspace(0.0, 1.0, 10)[1:]:  # underside, from the rim in to the keel
        add((1 - w) * origin + w * keel_centre, (1 - w) * 0.96 * tray + w * junction, -5.0)
    add(keel_centre, keel_radius(-5.6) + 0.5, -5.6)  # fillet
    for z in np.linspace(-6.5, -41.0, 18):  # keel
        add(keel_centre, keel_radius(z), z)
    for radius, z in [(4.3, -43.0), (3.2, -44.4), (1.7, -45.4)]:  # rounded tip
        add(keel_centre, np.full_like(theta, radius), z)

    directions = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    ring_points = np.array([
        np.column_stack([c + r[:, None] * directions, np.full(len(theta), z)]) for c, r, z in rings])
    top = np.array([0.0, 0.0, 0.0])
    tip = np.array([keel_centre[0], keel_centre[1], -45.8])
    return _oriented_outwards(*_ring_stack_surface(ring_points, top, tip))
