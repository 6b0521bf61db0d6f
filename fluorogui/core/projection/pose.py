"""Pose convention (docs/developer/conventions.rst): X = R m + t with
R = Ry(beta) @ Rz(gamma) @ Rx(alpha).

A pose is (x, y, z, alpha, beta, gamma) in millimetres and degrees. The matrix is the
transpose of the paper's Eq. (2) (written for row vectors), with the misprinted element
(3,1) read as sin(a)cos(b)sin(g) + cos(a)sin(b).
"""
from __future__ import annotations

import numpy as np

POSE_LABELS = ("x", "y", "z", "alpha", "beta", "gamma")
POSE_UNITS = ("mm", "mm", "mm", "deg", "deg", "deg")


def rotation_matrix(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """R = Ry(beta) @ Rz(gamma) @ Rx(alpha), angles in degrees, acting on column vectors."""
    a, b, g = np.radians([alpha, beta, gamma])
    ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    return np.array(
        [
            [cb * cg, -cb * sg * ca + sb * sa, cb * sg * sa + sb * ca],
            [sg, cg * ca, -cg * sa],
            [-sb * cg, sb * sg * ca + cb * sa, -sb * sg * sa + cb * ca],
        ]
    )


def paper_eq2_matrix(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """The paper's Eq. (2) exactly as printed but with element (3,1) corrected (row-vector form)."""
    a, b, g = np.radians([alpha, beta, gamma])
    ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    return np.array(
        [
            [cb * cg, sg, -sb * cg],
            [-ca * cb * sg + sa * sb, ca * cg, ca * sb * sg + sa * cb],
            [sa * cb * sg + ca * sb, -sa * cg, -sa * sb * sg + ca * cb],
        ]
    )


def angles_from_matrix(R: np.ndarray) -> tuple[float, float, float]:
    """(alpha, beta, gamma) in degrees from a rotation matrix of this convention."""
    R = np.asarray(R, dtype=float)
    gamma = np.arcsin(np.clip(R[1, 0], -1.0, 1.0))
    alpha = np.arctan2(-R[1, 2], R[1, 1])
    beta = np.arctan2(-R[2, 0], R[0, 0])
    return tuple(float(v) for v in np.degrees([alpha, beta, gamma]))


def as_pose(values) -> np.ndarray:
    """Validate and return a pose as a float array of six finite numbers."""
    pose = np.asarray(values, dtype=float).reshape(-1)
    if pose.shape != (6,):
        raise ValueError(f"a pose needs 6 numbers (x y z alpha beta gamma), got {pose.size}")
    if not np.all(np.isfinite(pose)):
        raise ValueError("the pose contains NaN or infinite values")
    return pose


def pose_to_matrix(pose) -> np.ndarray:
    """4x4 homogeneous model-to-world transform of a pose."""
    pose = np.asarray(pose, dtype=float)
    T = np.eye(4)
    T[:3, :3] = rotation_matrix(*pose[3:])
    T[:3, 3] = pose[:3]
    return T


def matrix_to_pose(T: np.ndarray) -> np.ndarray:
    """Pose (mm, deg) of a 4x4 transform (or of a (R, t) packed as 3x4)."""
    T = np.asarray(T, dtype=float)
    return np.array([*T[:3, 3], *angles_from_matrix(T[:3, :3])])


def transform_points(pose, points: np.ndarray) -> np.ndarray:
    """Model points (N, 3) to world coordinates with Eq. (1): R m + t."""
    pose = np.asarray(pose, dtype=float)
    return np.asarray(points, dtype=float) @ rotation_matrix(*pose[3:]).T + pose[:3]


def rotvec_matrix(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (radians), Rodrigues' formula."""
    w = np.asarray(w, dtype=float)
    th = float(np.linalg.norm(w))
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    if th < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(th) / th * K + (1 - np.cos(th)) / th**2 * (K @ K)


def pose_difference(estimate, truth) -> np.ndarray:
    """Per-DOF error (estimate - truth), angles wrapped to [-180, 180)."""
    d = np.asarray(estimate, dtype=float) - np.asarray(truth, dtype=float)
    d[3:] = (d[3:] + 180.0) % 360.0 - 180.0
    return d


def pose_error(estimate, truth) -> np.ndarray:
    """Error of a matched pose as the paper reports it, between body-fixed frames: the
    translation difference (mm) and the Euler angles (deg, this convention) of the rotation
    carrying the true frame onto the matched one, ``R_truth^T R_estimate``. Unlike
    differences of Euler angles it stays meaningful near gimbal lock (gamma ~ +/-90 deg)."""
    estimate, truth = np.asarray(estimate, dtype=float), np.asarray(truth, dtype=float)
    delta = rotation_matrix(*truth[3:]).T @ rotation_matrix(*estimate[3:])
    return np.r_[estimate[:3] - truth[:3], angles_from_matrix(delta)]


def body_difference(pose, reference, centroid) -> np.ndarray:
    """The body's own motion from ``reference`` to ``pose``: its ``centroid`` (model frame)
    shift in world mm, then its turn about its own model axes in degrees (the rotation
    vector of ``R_reference^T R_pose``), the frame ``MatchResult.sd_body`` is given in."""
    from scipy.spatial.transform import Rotation

    pose, reference = np.asarray(pose, dtype=float), np.asarray(reference, dtype=float)
    R0, R1 = rotation_matrix(*reference[3:]), rotation_matrix(*pose[3:])
    centroid = np.asarray(centroid, dtype=float)
    turn = np.degrees(Rotation.from_matrix(R0.T @ R1).as_rotvec())
    return np.r_[(R1 @ centroid + pose[:3]) - (R0 @ centroid + reference[:3]), turn]


def motion_between(pose_a, pose_b, point) -> tuple[float, float]:
    """How far a body moves between two poses: the distance (mm) travelled by ``point``
    (model frame, e.g. the mesh centroid) and the rotation angle (deg) between them."""
    pose_a, pose_b = np.asarray(pose_a, dtype=float), np.asarray(pose_b, dtype=float)
    Ra, Rb = rotation_matrix(*pose_a[3:]), rotation_matrix(*pose_b[3:])
    point = np.asarray(point, dtype=float)
    moved = (Ra @ point + pose_a[:3]) - (Rb @ point + pose_b[:3])
    cos = np.clip((np.trace(Ra.T @ Rb) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.linalg.norm(moved)), float(np.degrees(np.arccos(cos)))
