"""Triangle meshes of implant components: adjacency for silhouettes and even point clouds.

A mesh arrives as ``(vertices (N, 3) mm, faces (M, 3) int)`` from ``fluorogui.io.meshes.read``
or ``fluorogui.simulation.phantoms``. ``PreparedMesh`` precomputes what the matcher needs at
every evaluation: face normals and offsets (for the facing test against a source) and
the edge–face adjacency (silhouette edges lie between faces facing towards and away
from the source).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class MeshError(ValueError):
    """A mesh that cannot serve as an implant model."""


@dataclass(frozen=True)
class PreparedMesh:
    vertices: np.ndarray  # (N, 3)
    faces: np.ndarray  # (M, 3)
    face_normals: np.ndarray  # (M, 3) unit, outward for a consistently oriented mesh
    face_offsets: np.ndarray  # (M,) n . (a vertex of the face)
    edges: np.ndarray  # (E, 2) vertex indices of every edge shared by exactly two faces
    edge_faces: np.ndarray  # (E, 2) the two faces of each such edge
    open_edges: np.ndarray  # (B, 2) edges with one face or more than two: always candidates
    centroid: np.ndarray  # (3,) area-weighted surface centroid
    radius: float  # RMS distance of the surface from the centroid
    area: float
    #: derived data kept between calls (``face_edges``, ``core.projection.facing``'s references); not part
    #: of the mesh's identity, and a copy (``dataclasses.replace``) starts without it
    cache: dict = field(default_factory=dict, init=False, compare=False, repr=False)


def validate_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3:
        raise MeshError("mesh has fewer than 3 vertices")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise MeshError("mesh has no faces")
    if not np.all(np.isfinite(v)):
        raise MeshError("mesh vertices contain NaN or infinite values")
    f = f.astype(np.int64)
    if f.min() < 0 or f.max() >= len(v):
        raise MeshError("mesh faces refer to missing vertices")
    return v, f


def prepare_mesh(vertices, faces) -> PreparedMesh:
    v, f = validate_mesh(vertices, faces)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    cross = np.cross(b - a, c - a)
    double_area = np.linalg.norm(cross, axis=1)
    keep = double_area > 1e-12
    if not np.any(keep):
        raise MeshError("mesh has only degenerate (zero-area) faces")
    f, a, b, c, cross, double_area = f[keep], a[keep], b[keep], c[keep], cross[keep], double_area[keep]
    normals = cross / double_area[:, None]
    offsets = np.einsum("ij,ij->i", normals, a)

    # undirected edges with the faces that use them
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    face_of = np.tile(np.arange(len(f)), 3)
    e_sorted = np.sort(e, axis=1)
    key = e_sorted[:, 0] * (len(v) + 1) + e_sorted[:, 1]
    order = np.argsort(key, kind="stable")
    key, e_sorted, face_of = key[order], e_sorted[order], face_of[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    counts = np.diff(np.r_[starts, len(key)])
    pair = counts == 2
    edges = e_sorted[starts[pair]]
    edge_faces = np.column_stack([face_of[starts[pair]], face_of[starts[pair] + 1]])
    open_edges = e_sorted[starts[~pair]]

    areas = double_area / 2.0
    area = float(areas.sum())
    centroids = (a + b + c) / 3.0
    centroid = (centroids * areas[:, None]).sum(0) / area
    radius = float(np.sqrt((((centroids - centroid) ** 2).sum(1) * areas).sum() / area))
    return PreparedMesh(v, f, normals, offsets, edges, edge_faces, open_edges, centroid, radius, area)


def face_edges(mesh: PreparedMesh) -> np.ndarray:
    """(M, 3) for each face the indices into ``mesh.edges`` of its edges (b-c, c-a, a-b;
    -1 for an open edge). Made once per mesh and kept in its cache (read-only)."""
    out = mesh.cache.get("face_edges")
    if out is None:
        n = len(mesh.vertices) + 1
        f = mesh.faces
        sides = np.sort(np.stack([f[:, [1, 2]], f[:, [2, 0]], f[:, [0, 1]]], axis=1), axis=2)  # (M, 3, 2)
        key = sides[..., 0] * n + sides[..., 1]
        known = mesh.edges[:, 0] * n + mesh.edges[:, 1]  # ascending: prepare_mesh makes them in key order
        at = np.minimum(np.searchsorted(known, key), max(len(known) - 1, 0))
        out = np.where(known[at] == key, at, -1) if len(known) else np.full(key.shape, -1)
        out.flags.writeable = False
        mesh.cache["face_edges"] = out
    return out


def check_plausible_mm(vertices) -> None:
    """Refuse meshes whose size cannot be an implant in millimetres."""
    v = np.asarray(vertices, dtype=float)
    diag = float(np.linalg.norm(v.max(0) - v.min(0)))
    if diag < 1.0 or diag > 1000.0:
        raise MeshError(f"mesh is {diag:.3g} units across; is it in millimetres?")


def sample_surface(vertices, faces, n_points: int, seed: int = 0) -> np.ndarray:
    """An evenly spread cloud of about ``n_points`` points on the surface (exactly n_points).

    Area-weighted random candidates (eight per wanted point) are thinned to one per cell
    of a voxel grid whose size is found by bisection, which spreads them evenly (blue
    noise) instead of leaving the clumps of plain random sampling.
    """
    v, f = validate_mesh(vertices, faces)
    if n_points < 4:
        raise MeshError("a point model needs at least 4 points")
    rng = np.random.default_rng(seed)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    areas = np.linalg.norm(np.cross(b - a, c - a), axis=1) / 2.0
    total = areas.sum()
    n_cand = int(n_points) * 8
    tri = rng.choice(len(f), size=n_cand, p=areas / total)
    r1, r2 = rng.random(n_cand), rng.random(n_cand)
    s = np.sqrt(r1)
    cand = (1 - s)[:, None] * a[tri] + (s * (1 - r2))[:, None] * b[tri] + (s * r2)[:, None] * c[tri]

    lo = cand.min(0)

    def thin(h: float) -> np.ndarray:
        cells = np.floor((cand - lo) / h).astype(np.int64)
        key = (cells[:, 0] * 1_000_003 + cells[:, 1]) * 1_000_003 + cells[:, 2]
        # within a cell keep the candidate closest to the cell centre
        d = (((cand - lo) / h - cells - 0.5) ** 2).sum(1)
        order = np.lexsort((d, key))
        first = np.r_[True, key[order][1:] != key[order][:-1]]
        return order[first]

    h_lo, h_hi = 1e-3 * np.sqrt(total), 2.0 * np.sqrt(total)
    chosen = thin(h_lo)
    for _ in range(40):
        h = np.sqrt(h_lo * h_hi)
        idx = thin(h)
        if len(idx) >= n_points:
            h_lo, chosen = h, idx
        else:
            h_hi = h
        if abs(len(idx) - n_points) <= max(1, n_points // 200):
            if len(idx) >= n_points:
                chosen = idx
            break
    if len(chosen) < n_points:  # tiny request on a coarse grid: top up from the rest
        rest = np.setdiff1d(np.arange(n_cand), chosen)
        chosen = np.r_[chosen, rng.choice(rest, n_points - len(chosen), replace=False)]
    chosen = rng.permutation(chosen)[:n_points]
    return cand[np.sort(chosen)]
