"""Pinhole cameras of the bead calibration: the DLT, projection, and the decomposition of a
3x4 camera into ``K [R | t]`` refined as a zero-skew pinhole by least squares.

``P`` maps homogeneous world points (mm) to homogeneous pixels, rows down, beads in front
(positive depth); ``K`` upper triangular with a positive diagonal and ``K[2, 2] = 1``.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import rq
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation


def dlt(points3, points2) -> np.ndarray:
    """Hartley-normalised DLT: 3x4 P with points2 ~ P [points3; 1], beads in front (z > 0)."""
    return dlt_conditioned(points3, points2)[0]


def dlt_conditioned(points3, points2) -> tuple[np.ndarray, float]:
    """The DLT and how well it is determined (the ratio of the two smallest singular values
    of the normalised system; near 1 when two cameras fit equally, a degenerate sample)."""
    def normaliser(p):
        mean = p.mean(axis=0)
        spread = np.mean(np.linalg.norm(p - mean, axis=1))
        scale = np.sqrt(p.shape[1]) / spread if spread > 0 else 1.0
        T = np.eye(p.shape[1] + 1)
        T[:-1, :-1] *= scale
        T[:-1, -1] = -scale * mean
        return T

    points3, points2 = np.asarray(points3, dtype=float), np.asarray(points2, dtype=float)
    T3, T2 = normaliser(points3), normaliser(points2)
    X = np.column_stack([points3, np.ones(len(points3))]) @ T3.T
    x = np.column_stack([points2, np.ones(len(points2))]) @ T2.T
    zeros = np.zeros((len(X), 4))
    rows = np.empty((2 * len(X), 12))
    rows[0::2] = np.hstack([zeros, -x[:, 2:] * X, x[:, 1:2] * X])
    rows[1::2] = np.hstack([x[:, 2:] * X, zeros, -x[:, 0:1] * X])
    _, s, Vt = np.linalg.svd(rows, full_matrices=len(rows) < 12)
    s = np.concatenate([s, np.zeros(12 - len(s))])
    P = np.linalg.inv(T2) @ Vt[-1].reshape(3, 4) @ T3
    if np.mean(np.column_stack([points3, np.ones(len(points3))]) @ P[2]) < 0:
        P = -P  # beads in front of the source
    return P, float(s[-1] / s[-2]) if s[-2] > 0 else 1.0


def project(P, points3) -> np.ndarray:
    """Pixels of ``points3`` through P; a point on the source's plane lands far away (1e12)."""
    h = np.column_stack([points3, np.ones(len(points3))]) @ P.T
    w = h[:, 2:]
    safe = np.where(np.abs(w) > 1e-12 * np.abs(h[:, :2]).max(axis=1, keepdims=True), w, np.nan)
    return np.nan_to_num(h[:, :2] / safe, nan=1e12, posinf=1e12, neginf=-1e12)


def decompose(P) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    K, R = rq(P[:, :3])
    signs = np.diag(np.sign(np.diag(K)))
    K, R = K @ signs, signs @ R
    t = np.linalg.solve(K, P[:, 3])
    if np.linalg.det(R) < 0:
        R, t = -R, -t
    return K / K[2, 2], R, t


def refine(K, R, t, *, points3, points2, square_pixels: bool = True):
    """Least-squares pinhole (zero skew; one focal length when ``square_pixels``, which
    removes most of the focal-length / distance trade-off of a shallow phantom)."""
    n_intrinsic = 3 if square_pixels else 4

    def unpack(p):
        fx = p[0]
        fy = p[0] if square_pixels else p[1]
        cx, cy = p[n_intrinsic - 2:n_intrinsic]
        rest = p[n_intrinsic:]
        return np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]), Rotation.from_rotvec(rest[:3]).as_matrix(), rest[3:6]

    def residual(p):
        Kp, Rp, tp = unpack(p)
        return (project(Kp @ np.column_stack([Rp, tp]), points3) - points2).ravel()

    focal = [np.sqrt(K[0, 0] * K[1, 1])] if square_pixels else [K[0, 0], K[1, 1]]
    start = np.concatenate([focal, [K[0, 2], K[1, 2]], Rotation.from_matrix(R).as_rotvec(), t])
    solution = least_squares(residual, start, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
    return unpack(solution.x)
