"""Knee kinematics: the joint coordinate system of Grood & Suntay (1983) for the tibia
relative to the femur, from the two components' poses and their anatomical frames.

Anatomical frames (4×4, anatomical → model coordinates) have, for both knees, x to the
subject's right, y anterior, z proximal, origin at the joint centre. From them:

* e1 = the femoral x axis, e3 = the tibial z axis, e2 = e3 × e1 (normalised), the floating
  axis;
* flexion about e1, varus (adduction) about e2, internal rotation about e3, the three
  angles of the intrinsic x-y-z Cardan sequence of ``R_femur^T R_tibia``;
* translations: the femoral-origin → tibial-origin vector H written in the non-orthogonal
  basis, H = q1·e1 + q2·e2 + q3·e3.

Clinical signs, identical in name for both knees (``SIGN_CONVENTIONS``): flexion +,
varus +, internal rotation of the tibia +, medial, anterior tibial translation +,
distraction +. For a right knee, medial is the subject's left (−x); for a left knee the
mirror flips varus, internal rotation and medial back, so the names keep their meaning.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

SIDES = ("right", "left")
KINEMATICS_COLUMNS = ("flexion_deg", "varus_deg", "internal_deg", "medial_mm", "anterior_mm", "distraction_mm")
KINEMATICS_LABELS = ("Flexion", "Varus", "Internal rotation", "Medial translation", "Anterior translation",
                     "Distraction")
SIGN_CONVENTIONS = (
    "Grood & Suntay joint coordinate system of the tibia relative to the femur; "
    "e1 = femoral x (to the subject's right), e3 = tibial z (proximal), e2 = e3 x e1; "
    "anatomical frames x right, y anterior, z proximal for both knees; "
    "positive = flexion, varus (adduction), internal tibial rotation, medial, anterior and distal "
    "(distraction) tibial translation, for both knees; "
    "translations are the femoral-origin -> tibial-origin vector in the non-orthogonal basis e1, e2, e3"
)


class KinematicsError(ValueError):
    """An anatomical frame or pose that kinematics cannot use."""


@dataclass(frozen=True)
class KneeKinematics:
    """The six joint values of one frame (degrees, millimetres).

    Attributes
    ----------
    flexion_deg, varus_deg, internal_deg : float
        Flexion, varus (adduction) and internal rotation of the tibia, degrees.
    medial_mm, anterior_mm, distraction_mm : float
        Medial, anterior and distal (distraction) translation of the tibia, mm.
    """

    flexion_deg: float
    varus_deg: float
    internal_deg: float
    medial_mm: float
    anterior_mm: float
    distraction_mm: float

    def values(self) -> np.ndarray:
        return np.array([getattr(self, c) for c in KINEMATICS_COLUMNS])

    @classmethod
    def missing(cls) -> "KneeKinematics":
        return cls(*([float("nan")] * 6))


def check_side(side: str) -> str:
    side = str(side).strip().lower()
    if side not in SIDES:
        raise KinematicsError(f"side must be 'right' or 'left', not {side!r}")
    return side


def check_frame(matrix, tolerance: float = 1e-6) -> np.ndarray:
    """A 4×4 rigid transform (orthonormal rotation, det +1, last row 0 0 0 1) or KinematicsError."""
    try:
        T = np.asarray(matrix, dtype=float)
    except (TypeError, ValueError):
        raise KinematicsError("the frame is not a 4×4 matrix of numbers") from None
    if T.shape != (4, 4):
        raise KinematicsError(f"the frame must be a 4×4 matrix, not {T.shape}")
    if not np.all(np.isfinite(T)):
        raise KinematicsError("the frame holds NaN or infinite numbers")
    if not np.allclose(T[3], [0, 0, 0, 1], atol=tolerance):
        raise KinematicsError("the frame's last row must be 0 0 0 1")
    R = T[:3, :3]
    deviation = float(np.abs(R.T @ R - np.eye(3)).max())
    if deviation > tolerance:
        raise KinematicsError(f"the frame's rotation is not orthonormal (off by {deviation:.2g})")
    det = float(np.linalg.det(R))
    if abs(det - 1.0) > tolerance:
        raise KinematicsError(f"the frame's rotation has determinant {det:.6g}, not +1 (a mirror?)")
    return T


def joint_kinematics(femur_world, tibia_world, side: str = "right") -> KneeKinematics:
    """Grood & Suntay values from the two anatomical frames placed in the world.

    Parameters
    ----------
    femur_world, tibia_world : array_like of shape (4, 4)
        Anatomical → world: the component's pose matrix times its anatomical frame.
    side : {"right", "left"}, optional
        The knee's side; for a left knee varus, internal rotation and medial are mirrored
        back so the names keep their meaning.

    Returns
    -------
    KneeKinematics
        All NaN when a frame is not finite or at gimbal lock (varus of ±90°).

    Examples
    --------
    The tibia's frame built from six values, and the values back:

    >>> import numpy as np
    >>> tibia = relative_pose_from_kinematics([30, 2, 5, 1, 3, 40])
    >>> np.round(joint_kinematics(np.eye(4), tibia).values(), 6).tolist()
    [30.0, 2.0, 5.0, 1.0, 3.0, 40.0]
    """
    side = check_side(side)
    F = np.asarray(femur_world, dtype=float)
    T = np.asarray(tibia_world, dtype=float)
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(T))):
        return KneeKinematics.missing()
    I, J, K = F[:3, 0], F[:3, 1], F[:3, 2]  # noqa: E741 (Grood & Suntay's names)
    i, j, k = T[:3, 0], T[:3, 1], T[:3, 2]
    e1, e3 = I, k
    floating = np.cross(e3, e1)
    norm = float(np.linalg.norm(floating))
    if norm < 1e-9:  # gimbal lock: varus of ±90°, never seen in a knee
        return KneeKinematics.missing()
    e2 = floating / norm
    # angle about e1 from the femoral K to the plane of e2 and e3; about e3 from e2 to tibial j
    cardan_x = np.arctan2(-float(np.dot(J, k)), float(np.dot(K, k)))
    cardan_y = np.arcsin(np.clip(float(np.dot(I, k)), -1.0, 1.0))
    cardan_z = np.arctan2(-float(np.dot(j, I)), float(np.dot(i, I)))
    H = T[:3, 3] - F[:3, 3]
    q1, q2, q3 = np.linalg.solve(np.column_stack([e1, e2, e3]), H)
    mirror = 1.0 if side == "right" else -1.0
    return KneeKinematics(
        flexion_deg=float(np.degrees(-cardan_x)),
        varus_deg=float(np.degrees(mirror * cardan_y)),
        internal_deg=float(np.degrees(mirror * cardan_z)),
        medial_mm=float(-mirror * q1),
        anterior_mm=float(q2),
        distraction_mm=float(-q3),
    )


def knee_kinematics(femoral_pose_matrix, tibial_pose_matrix, femoral_frame, tibial_frame,
                    *, side: str = "right") -> KneeKinematics:
    """Knee kinematics (Grood & Suntay) from the two components' poses and anatomical frames.

    Parameters
    ----------
    femoral_pose_matrix, tibial_pose_matrix : array_like of shape (4, 4)
        The components' poses as model → world matrices
        (:func:`fluorogui.core.projection.pose.pose_to_matrix`).
    femoral_frame, tibial_frame : array_like of shape (4, 4)
        Anatomical → model frames (:func:`fluorogui.core.knee.anatomy.default_frame`, or
        the user's; :func:`check_frame` checks one).
    side : {"right", "left"}, optional

    Returns
    -------
    KneeKinematics

    Raises
    ------
    KinematicsError
        ``side`` is neither right nor left.

    Examples
    --------
    Both components upright and 40 mm apart along the tibial axis: no flexion, 40 mm of
    distraction.

    >>> import numpy as np
    >>> from fluorogui.core.projection.pose import pose_to_matrix
    >>> femur = pose_to_matrix([0, 0, 40, 0, 0, 0])
    >>> tibia = pose_to_matrix([0, 0, 0, 0, 0, 0])
    >>> k = knee_kinematics(femur, tibia, np.eye(4), np.eye(4), side="right")
    >>> round(k.flexion_deg, 6), round(k.distraction_mm, 6)
    (0.0, 40.0)
    """
    return joint_kinematics(np.asarray(femoral_pose_matrix) @ femoral_frame,
                            np.asarray(tibial_pose_matrix) @ tibial_frame, side)


def relative_pose_from_kinematics(values, side: str = "right") -> np.ndarray:
    """The tibial anatomical frame in the femoral anatomical frame (4×4) that gives the six
    ``values`` (the inverse of ``joint_kinematics`` with the femur at the identity)."""
    side = check_side(side)
    flexion, varus, internal, medial, anterior, distraction = (float(v) for v in values)
    mirror = 1.0 if side == "right" else -1.0
    a, b, c = np.radians([-flexion, mirror * varus, mirror * internal])
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    Rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    R = Rx @ Ry @ Rz
    e1, e3 = np.array([1.0, 0, 0]), R[:, 2]
    e2 = np.cross(e3, e1)
    e2 /= np.linalg.norm(e2)
    q = np.array([-mirror * medial, anterior, -distraction])
    out = np.eye(4)
    out[:3, :3] = R
    out[:3, 3] = np.column_stack([e1, e2, e3]) @ q
    return out


def kinematics_sd(femoral_pose, tibial_pose, femoral_frame, tibial_frame, *, side: str,
                  femoral_sd, tibial_sd, pose_matrix) -> np.ndarray:
    """Standard deviations of the six values from the poses' own (independent) SDs, by
    first-order propagation through central differences of the pose parameters.

    ``pose_matrix`` maps a 6-vector pose (mm, degrees) to its 4×4 (passed in so this module
    needs no pose convention); NaN where an SD is missing.
    """
    poses = [np.asarray(femoral_pose, dtype=float), np.asarray(tibial_pose, dtype=float)]
    sds = [np.asarray(femoral_sd, dtype=float).reshape(6), np.asarray(tibial_sd, dtype=float).reshape(6)]
    if not all(np.all(np.isfinite(s)) for s in sds):
        return np.full(6, np.nan)
    frames = [femoral_frame, tibial_frame]

    def values(p0, p1) -> np.ndarray:
        return knee_kinematics(pose_matrix(p0), pose_matrix(p1), frames[0], frames[1], side=side).values()

    variance = np.zeros(6)
    for which in (0, 1):
        for k in range(6):
            step = 1e-4
            plus, minus = [p.copy() for p in poses], [p.copy() for p in poses]
            plus[which][k] += step
            minus[which][k] -= step
            derivative = (values(*plus) - values(*minus)) / (2 * step)
            variance += (derivative * sds[which][k]) ** 2
    return np.sqrt(variance)


def moved_by_body(matrix, motion, centroid) -> np.ndarray:
    """A 4×4 pose moved by the body's own motion (``MatchResult.sd_body``'s frame): its
    ``centroid`` (model frame, mm) shifted by ``motion[:3]`` (world mm) and the body turned
    about that centroid by the rotation vector ``motion[3:]`` (degrees, about its own model
    axes: ``R' = R exp(turn)``)."""
    matrix = np.asarray(matrix, dtype=float)
    motion, centroid = np.asarray(motion, dtype=float), np.asarray(centroid, dtype=float)
    R = matrix[:3, :3] @ Rotation.from_rotvec(motion[3:], degrees=True).as_matrix()
    out = matrix.copy()
    out[:3, :3] = R
    out[:3, 3] = matrix[:3, :3] @ centroid + matrix[:3, 3] + motion[:3] - R @ centroid
    return out


def kinematics_sd_body(femoral_matrix, tibial_matrix, femoral_frame, tibial_frame, *, side: str,
                       femoral_cov, tibial_cov, femoral_centroid, tibial_centroid) -> np.ndarray:
    """Standard deviations of the six values from each component's uncertainty of its own
    motion: ``*_cov`` the 6×6 covariance of its centroid (world mm) and its turn about its
    model axes (deg) (``MatchResult.cov_body``), or those six SDs alone (taken as
    independent). First order, by central differences; the two components' errors are
    independent of each other. NaN where a covariance is missing or not finite.

    Unlike ``kinematics_sd`` this is free of the Euler angles' coupling: near gimbal lock
    two Euler angles of one pose trade against each other, so their SDs are large and,
    propagated as if independent, overstate the knee's uncertainty many times.
    """
    matrices = [np.asarray(femoral_matrix, dtype=float), np.asarray(tibial_matrix, dtype=float)]
    centroids = [femoral_centroid, tibial_centroid]
    covs = []
    for cov in (femoral_cov, tibial_cov):
        cov = np.asarray(cov, dtype=float)
        cov = np.diag(cov.reshape(6) ** 2) if cov.size == 6 else cov.reshape(6, 6)
        if not np.all(np.isfinite(cov)):
            return np.full(6, np.nan)
        covs.append(cov)
    frames = [femoral_frame, tibial_frame]

    def values(which: int, motion) -> np.ndarray:
        moved = list(matrices)
        moved[which] = moved_by_body(matrices[which], motion, centroids[which])
        return knee_kinematics(moved[0], moved[1], frames[0], frames[1], side=side).values()

    variance = np.zeros(6)
    step = 1e-4
    for which in (0, 1):
        J = np.zeros((6, 6))
        for k in range(6):
            d = np.zeros(6)
            d[k] = step
            J[:, k] = (values(which, d) - values(which, -d)) / (2 * step)
        variance += np.einsum("ij,jk,ik->i", J, covs[which], J)
    return np.sqrt(np.maximum(variance, 0.0))
