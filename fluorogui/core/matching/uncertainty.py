"""The uncertainty of a matched pose: its covariance from the Gauss-Newton matrix of the
fast method's residuals, with neighbouring outline points counted together in stretches
(they share edge noise, blur and segmentation), and the six standard deviations."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from fluorogui.core.matching.fast import _FastEvaluation, _samples_and_params
from fluorogui.core.matching.problem import MatchProblem, MatchSettings, _to_pose, _to_state
from fluorogui.core.projection.pose import as_pose, pose_difference, rotvec_matrix

# -- uncertainty ---------------------------------------------------------------------------------
#: length (px along the image outline) of the stretches whose residuals are taken as one
#: independent unit: neighbouring outline points share edge noise, blur and segmentation
#: (measured on outlines with noise correlated over ~4 px: 24 px stretches still gave SDs
#: 0.7x the observed spread, 48 px 0.73-1.34x; tests/core/test_matching_uncertainty.py)
CLUSTER_PX = 48.0
#: ... but at least this many stretches per view (small outlines)
MIN_STRETCHES = 8


def pose_covariance(problem: MatchProblem, pose, *, settings: MatchSettings | None = None,
                    cluster_px: float = CLUSTER_PX, evaluation: tuple | None = None) -> np.ndarray:
    """Covariance (6x6; mm and degrees) of the pose variables x, y, z, alpha, beta, gamma
    (``covariances`` gives it together with the body's)."""
    return covariances(problem, pose, settings=settings, cluster_px=cluster_px, evaluation=evaluation)[0]


def covariances(problem: MatchProblem, pose, *, settings: MatchSettings | None = None,
                cluster_px: float = CLUSTER_PX, evaluation: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Covariances (6x6; mm and degrees) of the pose variables x, y, z, alpha, beta, gamma,
    and of the body's own motion: its centroid (world x, y, z) and its turn about its own
    model axes x, y, z (free of the Euler angles' coupling, e.g. near gimbal lock).

    Gauss-Newton (Laplace) at ``pose`` with the residuals' own variance, as a sandwich
    H^-1 B H^-1: H is the Gauss-Newton matrix of the fast objective and B sums the
    gradient contributions of the residuals in stretches of ``cluster_px`` of image
    outline (both directions of residual in one stretch together), so residuals that are
    correlated along the outline (blur, segmentation, a systematic misfit) count as one
    sample per stretch instead of one per point. Infinite where the outlines do not fix
    a direction of motion."""
    settings = replace(settings or MatchSettings(), method="fast")
    mesh = problem.mesh
    pose = as_pose(pose)
    R, c = _to_state(pose, mesh.centroid)
    if evaluation is not None and np.allclose(evaluation[0], pose, rtol=0, atol=1e-12):
        ev = evaluation[1]  # the matcher's own last evaluation at this pose
    else:
        samples, params = _samples_and_params(problem, settings)
        ev = _FastEvaluation(problem, R, c, settings, samples, params)
    H = np.zeros((6, 6))
    all_scores, all_keys, all_hessians = [], [], []
    for r, J, w, k, where in zip(ev.r, ev.J, ev.w, ev.view_of, ev.where):
        a = np.abs(r)
        ww = w * np.where(a <= settings.huber_px, 1.0, settings.huber_px / np.maximum(a, 1e-12))
        H += J.T @ (J * ww[:, None])
        all_scores.append(J * (ww * r)[:, None])
        all_hessians.append(np.einsum("ni,nj->nij", J, J * ww[:, None]))
        spline = problem.splines[k]
        length = min(cluster_px, spline.period / MIN_STRETCHES)
        stretch = np.floor((spline.wrap(where) - spline.t_range[0]) / length).astype(np.int64)
        all_keys.append(k * 1_000_000 + stretch)
    keys, group = np.unique(np.concatenate(all_keys), return_inverse=True)
    n = len(keys)
    eig = np.linalg.eigvalsh(H)
    if n <= 6 or eig[0] <= 1e-12 * max(eig[-1], 1e-300):
        return np.full((6, 6), np.inf), np.full((6, 6), np.inf)
    S = _sum_by(group.ravel(), np.vstack(all_scores), n)
    Hg = _sum_by(group.ravel(), np.concatenate(all_hessians).reshape(-1, 36), n).reshape(n, 6, 6)
    # the jackknife over stretches (CR3): each stretch's own effect on the pose, with the
    # stretch left out of H. A plain sandwich H^-1 (sum s s^T) H^-1 is biased low when
    # there are few stretches for six variables (a single view: about a dozen).
    left_out = H[None] - Hg
    if np.any(np.linalg.eigvalsh(left_out)[:, 0] <= 1e-12 * max(eig[-1], 1e-300)):
        return np.full((6, 6), np.inf), np.full((6, 6), np.inf)  # one stretch alone fixes a direction
    shifts = np.linalg.solve(left_out, S[..., None])[..., 0]  # (n, 6)
    cov = shifts.T @ shifts * (n - 1) / n
    # from the matcher's variables (centroid shift, rotation vector x radius) to the pose's
    A = np.zeros((6, 6))
    h = 1e-4
    for j in range(6):
        d = np.zeros(6)
        d[j] = h
        plus = _to_pose(rotvec_matrix(d[3:] / mesh.radius) @ R, c + d[:3], mesh.centroid)
        d[j] = -h
        minus = _to_pose(rotvec_matrix(d[3:] / mesh.radius) @ R, c + d[:3], mesh.centroid)
        A[:, j] = pose_difference(plus, minus) / (2 * h)
    # the body's own motion: centroid as it is; the world rotation vector (x radius) turned
    # into the model frame, in degrees
    B = np.eye(6)
    B[3:, 3:] = R.T * np.degrees(1.0 / mesh.radius)
    return A @ cov @ A.T, B @ cov @ B.T


def _sum_by(group: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    """Sums (n, m) of ``rows`` (N, m) by their ``group`` index: one bincount per column (the
    unbuffered np.add.at did the same sums a dozen times slower)."""
    return np.column_stack([np.bincount(group, weights=column, minlength=n) for column in rows.T])


def pose_sd(cov: np.ndarray) -> list[float]:
    """Standard deviations (mm, deg) from a pose covariance."""
    return [float(np.sqrt(v)) if np.isfinite(v) and v >= 0 else float("inf") for v in np.diag(cov)]
