"""Bone and cement about an implant, for the X-ray image model (``fluorogui.reference.xray``).

On real fluoroscopy the bone side of a tibial tray is not a flat background: under the
plate and around the keel the cement mantle and the dense bone next to it darken the image
at the metal's edge, and the level rises over 10-20 px outward. A ``Zone`` makes that: an
attenuation ``mu / (1 + exp((d - thickness) / softness))`` at distance ``d`` (mm) from the
implant's surface, on the side of a plane where the bone is (the plate's underside,
softened the same way), integrated along each ray.

The distance is taken on a voxel grid (``voxel`` mm) aligned with the implant's principal
axes: the surface is sampled densely and its voxels marked; a Euclidean distance transform
finds each voxel's nearest marked one, and the distance is taken to the mean of the surface
samples in it (the integrals are within 1.5 % of exact ones at 0.4 mm voxels, 4 % in the
far tail). The ray integral is a sum of trilinear samples every ``voxel`` mm, at pixel
centres only: the zone is smooth, so the X-ray model interpolates it to its sub-pixel
samples. Inside the metal the zone adds a little to the metal's attenuation (the metal
stays black). Only numpy and scipy; no import from ``fluorogui``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import distance_transform_edt, map_coordinates


@dataclass
class Zone:
    """Bone and cement about the implant surface ``vertices`` / ``faces`` (world mm).

    ``mu`` (1/mm) next to the surface, half of it at ``thickness`` mm, falling over
    ``softness`` mm; only on the side of ``plane`` = (point, normal) the normal points to
    (None: all round)."""

    vertices: np.ndarray
    faces: np.ndarray
    mu: float
    thickness: float
    softness: float
    plane: tuple | None = None
    voxel: float = 0.4
    _grid: tuple | None = field(default=None, repr=False)

    def reach(self) -> float:
        """How far (mm) from the surface the zone is kept: where it is below 1 % of ``mu``."""
        return self.thickness + 4.6 * self.softness

    def grid(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(origin (3,), axes (3, 3) as rows, attenuation grid (nx, ny, nz)): the point of
        index (i, j, k) is origin + voxel * (i, j, k) @ axes."""
        if self._grid is None:
            self._grid = self._build()
        return self._grid

    def _build(self):
        V = np.asarray(self.vertices, dtype=float)
        F = np.asarray(self.faces, dtype=np.int64)
        centre = V.mean(0)
        axes = np.linalg.svd(V - centre, full_matrices=False)[2]  # principal axes, rows
        local = (V - centre) @ axes.T
        pad = self.reach() + 2 * self.voxel
        lo = local.min(0) - pad
        shape = np.ceil((local.max(0) + pad - lo) / self.voxel).astype(int) + 1
        origin = centre + lo @ axes
        # the surface's voxels, from samples at most a third of a voxel apart, and the mean
        # of the samples in each (the surface's point there)
        shape = tuple(int(n) for n in shape)
        tri = local[F]
        longest = np.max(np.linalg.norm(tri - tri[:, [1, 2, 0]], axis=2), axis=1)
        steps = np.maximum(1, np.ceil(3 * longest / self.voxel)).astype(int)
        samples = []
        for n in np.unique(steps):
            i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
            keep = i + j <= n
            wa, wb = i[keep] / n, j[keep] / n
            t = tri[steps == n]
            samples.append((t[:, None, 0] * (1 - wa - wb)[None, :, None] + t[:, None, 1] * wa[None, :, None]
                            + t[:, None, 2] * wb[None, :, None]).reshape(-1, 3))
        points = np.vstack(samples)
        idx = np.clip(np.round((points - lo) / self.voxel).astype(np.int64), 0, np.array(shape) - 1)
        flat = np.ravel_multi_index(idx.T, shape)
        count = np.bincount(flat, minlength=int(np.prod(shape)))
        marked = np.nonzero(count)[0]
        surface_point = np.column_stack([np.bincount(flat, weights=points[:, k], minlength=len(count))[marked]
                                         for k in range(3)]) / count[marked, None]
        del points, flat, idx, samples
        surface = np.zeros(shape, dtype=bool)
        surface.flat[marked] = True
        # each node's nearest surface voxel (a distance transform), then its exact distance
        # to that voxel's surface point
        nearest = np.zeros((3,) + shape, dtype=np.int32)
        distance_transform_edt(~surface, return_distances=False, return_indices=True, indices=nearest)
        row = np.zeros(int(np.prod(shape)), dtype=np.int32)
        row[marked] = np.arange(len(marked), dtype=np.int32)
        which = row[np.ravel_multi_index(nearest.reshape(3, -1), shape)]
        del nearest
        nodes = np.stack(np.meshgrid(*(lo[k] + self.voxel * np.arange(shape[k], dtype=np.float32) for k in range(3)),
                                     indexing="ij"), axis=-1).reshape(-1, 3)
        d = np.linalg.norm(nodes - surface_point[which], axis=1).reshape(shape).astype(np.float32)
        del nodes, which
        rho = self.mu / (1.0 + np.exp(np.minimum((d - self.thickness) / self.softness, 60.0)))
        if self.plane is not None:
            point, normal = (np.asarray(a, dtype=float) for a in self.plane)
            normal = normal / np.linalg.norm(normal)
            coords = [lo[k] + self.voxel * np.arange(shape[k]) for k in range(3)]
            # signed distance to the plane: linear in the local coordinates
            n_local = axes @ normal
            offset = (centre - point) @ normal
            side = (offset + coords[0][:, None, None] * n_local[0] + coords[1][None, :, None] * n_local[1]
                    + coords[2][None, None, :] * n_local[2])
            rho = rho / (1.0 + np.exp(np.clip(-side / self.softness, -60.0, 60.0)))
        # kept only where it counts (above 1/1000 of mu): fewer samples along each ray
        keep = np.nonzero(rho > 1e-3 * self.mu)
        if not len(keep[0]):
            return origin, axes, np.zeros((1, 1, 1), dtype=np.float32)
        first = np.maximum(np.array([k.min() for k in keep]) - 1, 0)
        last = np.minimum(np.array([k.max() for k in keep]) + 2, shape)
        rho = rho[first[0]:last[0], first[1]:last[1], first[2]:last[2]]
        return origin + (self.voxel * first) @ axes, axes, np.ascontiguousarray(rho, dtype=np.float32)

    def integral(self, view, u: np.ndarray, v: np.ndarray, chunk: int = 4_000_000) -> np.ndarray:
        """sum(mu L) of the zone along the rays from the source through pixels (u, v)."""
        origin, axes, rho = self.grid()
        shape = np.array(rho.shape)
        u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
        d = (view.distance * np.asarray(view.normal, dtype=float)[None, :]
             + ((u.reshape(-1) - view.principal_point[0]) * view.pitch[0])[:, None] * np.asarray(view.e_u)[None, :]
             + ((v.reshape(-1) - view.principal_point[1]) * view.pitch[1])[:, None] * np.asarray(view.e_v)[None, :])
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        # rays in the grid's index coordinates: x = s + t * e (t in mm)
        s = (np.asarray(view.source, dtype=float) - origin) @ axes.T / self.voxel
        e = d @ axes.T / self.voxel
        # where the ray meets the grid's box (slabs; a ray parallel to one is in it or not)
        flat = np.abs(e) < 1e-12
        safe = np.where(flat, 1.0, e)
        t0, t1 = (0.0 - s[None, :]) / safe, (shape - 1 - s[None, :]) / safe
        inside = (s >= 0) & (s <= shape - 1)
        lo = np.where(flat, np.where(inside[None, :], -np.inf, np.inf), np.minimum(t0, t1))
        hi = np.where(flat, np.where(inside[None, :], np.inf, -np.inf), np.maximum(t0, t1))
        near, far = lo.max(axis=1), hi.min(axis=1)
        hit = np.nonzero(far > near)[0]
        out = np.zeros(len(d))
        if not len(hit):
            return out.reshape(np.shape(u))
        counts = np.ceil((far[hit] - near[hit]) / self.voxel).astype(np.int64)
        start = 0
        while start < len(hit):
            cum = np.cumsum(counts[start:])
            stop = start + max(1, int(np.searchsorted(cum, chunk)))
            rays, n = hit[start:stop], counts[start:stop]
            owner = np.repeat(np.arange(len(rays)), n)
            k = np.arange(owner.size) - np.repeat(np.cumsum(n) - n, n)
            t = (near[rays][owner] + (k + 0.5) * self.voxel).astype(np.float32)
            x = s.astype(np.float32)[None, :] + t[:, None] * e[rays].astype(np.float32)[owner]
            values = map_coordinates(rho, x.T, order=1, mode="constant", cval=0.0, prefilter=False)
            out[rays] += np.bincount(owner, weights=values, minlength=len(rays)) * self.voxel
            start = stop
        return out.reshape(np.shape(u))


#: a tibial tray's bone and cement on the real biplane data (``tools/edge_profiles.py``: the
#: intensity along the outline's normals under the plate and beside the keel, as a share of
#: the rise from the metal to 30 px out, matched by X-ray model images of the same poses):
#: 1/mm next to the metal, the half-way distance and the fall-off (mm)
TRAY_MU, TRAY_THICKNESS, TRAY_SOFTNESS = 0.03, 3.0, 0.5
#: the blur (Gaussian sigma, px) of the real images, for ``XrayModel.detector_blur_px``: an
#: error function fitted to each profile across the plate's top edge (facing the joint
#: space) gives a median sigma of 1.36 px in view 1 and 1.54 px in view 2 on 12 real
#: frames, and 1.33 px on model images made with 1.2 px (pixel and sampling add the rest)
REAL_BLUR_PX = 1.3


def plate_underside(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The model z (mm) of a tibial tray's plate underside, where the cut bone meets it: of
    the faces that look down (model z proximal; the keel's tip left out), the height below
    which a tenth of their area lies (the rim of an underside recessed for cement)."""
    P = np.asarray(vertices, dtype=float)[np.asarray(faces, dtype=np.int64)]
    n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    area = np.linalg.norm(n, axis=1)
    z = P[:, :, 2].mean(1)
    down = (n[:, 2] < -0.9 * np.maximum(area, 1e-12)) & (z > P[:, :, 2].min() + 5.0)
    if not down.any():
        raise ValueError("the mesh has no face looking down above its lowest 5 mm: not a tray in its own frame")
    order = np.argsort(z[down])
    cumulative = np.cumsum(area[down][order])
    return float(z[down][order][np.searchsorted(cumulative, cumulative[-1] / 10)])


def tray_zone(vertices: np.ndarray, faces: np.ndarray, pose_matrix: np.ndarray, *, mu: float = TRAY_MU,
              thickness: float = TRAY_THICKNESS, softness: float = TRAY_SOFTNESS) -> Zone:
    """The bone and cement under a tibial tray's plate and around its keel: the tray's mesh
    in its own frame (z proximal), placed by the 4 x 4 model -> world ``pose_matrix``."""
    M = np.asarray(pose_matrix, dtype=float)
    world = np.asarray(vertices, dtype=float) @ M[:3, :3].T + M[:3, 3]
    point = M[:3, :3] @ np.array([0.0, 0.0, plate_underside(vertices, faces)]) + M[:3, 3]
    return Zone(world, np.asarray(faces), mu, thickness, softness, (point, -M[:3, 2]))
