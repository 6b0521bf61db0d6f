"""The closest point of a triangle mesh to given points, exactly (not the nearest vertex).

``closest_on_triangles`` is the closest point of each point's own triangle (the Voronoi
regions of a triangle's vertices, edges and face; Ericson, *Real-Time Collision
Detection*, 2005, §5.1.5), vectorised. ``TriangleSurface`` finds, for many points, the
closest point over a whole mesh: each triangle is covered by sample points (the centroids
of the similar triangles it is cut into) no farther than ``cover`` from any point of it,
kept in a k-d tree. The triangles of a point's nearest samples give an upper bound ``ub``
of the distance, and only triangles with a sample within ``ub + cover`` can hold a closer
point: when the nearest samples fetched do not reach that far, every sample within it is
fetched, so the answer is exact whatever the triangles' sizes. Used by the contact
kinematics (``core.knee.contact``) and to state the surface error of a simplified mesh.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def closest_on_triangles(points, a, b, c) -> np.ndarray:
    """The closest point to ``points[i]`` on the triangle ``(a[i], b[i], c[i])``; all (n, 3)."""
    p, a, b, c = (np.asarray(x, dtype=float) for x in (points, a, b, c))
    ab, ac = b - a, c - a
    d1, d2 = _dot(ab, p - a), _dot(ac, p - a)
    d3, d4 = _dot(ab, p - b), _dot(ac, p - b)
    d5, d6 = _dot(ab, p - c), _dot(ac, p - c)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v, w = _safe(vb / denom), _safe(vc / denom)
        out = a + ab * v[:, None] + ac * w[:, None]  # inside the face
        # the regions in the reverse of Ericson's order, so that his first test wins
        t = _safe((d4 - d3) / ((d4 - d3) + (d5 - d6)))
        _put(out, (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * t[:, None])  # edge BC
        t = _safe(d2 / (d2 - d6))
        _put(out, (vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t[:, None])  # edge CA
        _put(out, (d6 >= 0) & (d5 <= d6), c)  # vertex C
        t = _safe(d1 / (d1 - d3))
        _put(out, (vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t[:, None])  # edge AB
        _put(out, (d3 >= 0) & (d4 <= d3), b)  # vertex B
        _put(out, (d1 <= 0) & (d2 <= 0), a)  # vertex A
    return out


def _dot(u, v) -> np.ndarray:
    return np.einsum("ij,ij->i", u, v)


def _safe(x) -> np.ndarray:
    return np.where(np.isfinite(x), x, 0.0)


def _put(out, mask, values) -> None:
    out[mask] = values[mask]


class TriangleSurface:
    """A triangle mesh that answers closest-point queries exactly.

    Parameters
    ----------
    vertices : array_like of shape (N, 3)
    faces : array_like of shape (M, 3)
    cover : float, optional
        How far any point of a triangle may be from its nearest sample (mm); by default
        the median edge length. Smaller is faster per query, larger builds faster.
    """

    def __init__(self, vertices, faces, cover: float | None = None):
        self.vertices = np.asarray(vertices, dtype=float)
        self.faces = np.asarray(faces, dtype=np.int64)
        a, b, c = (self.vertices[self.faces[:, i]] for i in range(3))
        edges = np.stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                          np.linalg.norm(a - c, axis=1)], axis=1)
        longest = edges.max(axis=1)
        if cover is None:
            cover = float(np.median(edges)) if len(edges) else 1.0
        cover = max(float(cover), 1e-9)
        # each triangle cut into n x n similar ones, a sample at each one's centroid: every
        # point of it then lies within (the farthest corner from the centroid) / n of a sample
        centroid = (a + b + c) / 3.0
        corner = np.max(np.stack([np.linalg.norm(x - centroid, axis=1) for x in (a, b, c)]), axis=0)
        splits = np.maximum(1, np.ceil(longest / cover)).astype(np.int64)
        self.cover = float(np.max(corner / splits)) if len(splits) else cover
        samples, owners = [], []
        for n in np.unique(splits):
            which = np.flatnonzero(splits == n)
            i, j = (x.ravel() for x in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
            up, down = i + j <= n - 1, i + j <= n - 2
            u = np.concatenate([(i[up] + 1 / 3) / n, (i[down] + 2 / 3) / n])  # barycentric weights of b and c
            v = np.concatenate([(j[up] + 1 / 3) / n, (j[down] + 2 / 3) / n])
            pa, pb, pc = a[which], b[which], c[which]
            grid = (pa[:, None, :] * (1 - u - v)[None, :, None] + pb[:, None, :] * u[None, :, None]
                    + pc[:, None, :] * v[None, :, None])
            samples.append(grid.reshape(-1, 3))
            owners.append(np.repeat(which, len(u)))
        self._samples = np.concatenate(samples) if samples else np.empty((0, 3))
        self._owner = np.concatenate(owners) if owners else np.empty(0, np.int64)
        self._tree = cKDTree(self._samples)
        self._a, self._b, self._c = a, b, c

    #: samples fetched per point at once; more only where they do not reach far enough
    NEIGHBOURS = 16

    def closest(self, points, chunk: int = 16384) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each point: the distance to the mesh, the closest point on it and its triangle.

        Returns
        -------
        distance : numpy.ndarray of shape (n,)
        closest : numpy.ndarray of shape (n, 3)
        face : numpy.ndarray of shape (n,) int
        """
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        distance, best, face = np.empty(len(p)), np.empty((len(p), 3)), np.empty(len(p), np.int64)
        for start in range(0, len(p), chunk):
            part = slice(start, start + chunk)
            distance[part], best[part], face[part] = self._closest(p[part])
        return distance, best, face

    def _closest(self, p: np.ndarray):
        k = min(self.NEIGHBOURS, len(self._samples))
        reach, nearest = self._tree.query(p, k)
        reach, nearest = reach.reshape(len(p), k), nearest.reshape(len(p), k)
        faces = self._owner[nearest.ravel()]
        candidate = closest_on_triangles(np.repeat(p, k, axis=0), self._a[faces], self._b[faces], self._c[faces])
        d = np.linalg.norm(candidate - np.repeat(p, k, axis=0), axis=1).reshape(len(p), k)
        pick = np.argmin(d, axis=1)
        rows = np.arange(len(p))
        distance = d[rows, pick]
        best = candidate.reshape(len(p), k, 3)[rows, pick]
        face = faces.reshape(len(p), k)[rows, pick]
        # exact when the k samples include every one within distance + cover; else all those
        short = np.flatnonzero((reach[:, -1] <= distance + self.cover) & (k < len(self._samples)))
        if len(short):
            lists = self._tree.query_ball_point(p[short], distance[short] + self.cover + 1e-9, return_sorted=False)
            counts = np.fromiter((len(x) for x in lists), dtype=np.int64, count=len(lists))
            which = np.repeat(np.arange(len(short)), counts)
            samples = np.fromiter((s for x in lists for s in x), dtype=np.int64, count=int(counts.sum()))
            d, q, f = self._best(p[short], which, self._owner[samples], len(short))
            distance[short], best[short], face[short] = d, q, f
        return distance, best, face

    def _best(self, p: np.ndarray, which: np.ndarray, faces: np.ndarray, n: int):
        """Per point, the closest of its candidate triangles (``which``: the point of each)."""
        count = np.int64(len(self.faces))
        key = np.unique(which.astype(np.int64) * count + faces)
        q, f = key // count, key % count
        candidate = closest_on_triangles(p[q], self._a[f], self._b[f], self._c[f])
        d = np.linalg.norm(candidate - p[q], axis=1)
        order = np.lexsort((d, q))
        first = order[np.r_[True, q[order][1:] != q[order][:-1]]]
        distance, best, face = np.full(n, np.inf), np.zeros((n, 3)), np.zeros(n, np.int64)
        distance[q[first]], best[q[first]], face[q[first]] = d[first], candidate[first], f[first]
        return distance, best, face

    def nearest_sample(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each point, its nearest sample of the mesh: the distance (at least the
        distance to the mesh, at most ``cover`` more), the sample and its triangle."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        distance, index = self._tree.query(p)
        return distance, self._samples[index], self._owner[index]

    def distance_to_faces(self, points, face) -> tuple[np.ndarray, np.ndarray]:
        """The distance from each point to the given triangle of it (at least its distance to
        the mesh) and the closest point of that triangle."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        face = np.asarray(face, dtype=np.int64)
        closest = closest_on_triangles(p, self._a[face], self._b[face], self._c[face])
        return np.linalg.norm(closest - p, axis=1), closest

    def face_normals(self, face) -> np.ndarray:
        """Unit normals (by the faces' winding) of the given triangles."""
        face = np.asarray(face, dtype=np.int64)
        n = np.cross(self._b[face] - self._a[face], self._c[face] - self._a[face])
        return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
