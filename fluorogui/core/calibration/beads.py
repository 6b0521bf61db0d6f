"""Geometry of one fluoroscope view from an image of a bead phantom of known layout.

Steps (the paper rebuilds each view's projection from such a phantom):

1. ``detect_beads``: dark round blobs (metal beads on a bright field), sub-pixel centres
   from their darkness-weighted centroid, and their areas. The phantom's first bead is
   larger: the largest blob (at least ``MARKER_AREA_RATIO`` times the typical one) is it.
2. ``match_beads``: correspondence by RANSAC over affine cameras. The marker fixes one
   pair; three more phantom beads (the largest tetrahedra with the marker) are paired with
   every ordered triple of detected beads, each hypothesis's affine camera projects the
   whole phantom, and the one with most beads landing on a detection wins. Its pairs seed a
   DLT, which re-pairs the beads with perspective included, until nothing changes.
   Detections that no phantom bead lands on are outliers and are dropped.
3. ``calibrate_view``: DLT (Hartley-normalised), decomposed into ``K [R | t]`` and refined
   as a zero-skew pinhole by least squares on the reprojection error; then converted to
   DESIGN.md's view (source ``-R^T t``, normal ``R^T e_z``, ``l = f * pitch``). Reports the
   reprojection error per bead and the source–intensifier distance.

Too few beads, an unmatched phantom and a (nearly) coplanar phantom are refused with a
``BeadError`` saying which.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.linalg import rq
from scipy.optimize import least_squares
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from fluorogui.core.projection.geometry import DEFAULT_PITCH_MM, GeometryError, View

MIN_BEADS = 8
MARKER_AREA_RATIO = 1.8
COPLANAR_RATIO = 0.05


class BeadError(ValueError):
    """No calibration from these beads; ``about_phantom`` when the phantom file is at fault."""

    def __init__(self, message: str, about_phantom: bool = False):
        super().__init__(message)
        self.about_phantom = about_phantom


def check_phantom(beads: np.ndarray) -> np.ndarray:
    beads = np.asarray(beads, dtype=float)
    if beads.ndim != 2 or beads.shape[1] != 3:
        raise BeadError("the phantom needs x, y, z per bead", about_phantom=True)
    if len(beads) < MIN_BEADS:
        raise BeadError(f"too few beads in the phantom: {len(beads)} (need at least {MIN_BEADS})", about_phantom=True)
    spread = np.linalg.svd(beads - beads.mean(axis=0), compute_uv=False)
    if spread[2] < COPLANAR_RATIO * spread[0]:
        raise BeadError("the phantom's beads are (nearly) coplanar; a projection needs beads at several depths "
                        f"(thickness ratio {spread[2] / spread[0]:.3f} < {COPLANAR_RATIO})", about_phantom=True)
    return beads


def detect_beads(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (M, 2) in pixels and areas (M,) of the dark round blobs of ``image``."""
    img = np.asarray(image, dtype=np.float32)
    smooth = cv2.GaussianBlur(img, (0, 0), 1.0)
    scaled = cv2.normalize(smooth, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    level, mask = cv2.threshold(scaled, 0, 255, cv2.THRESH_BINARY_INV + cv2.THRESH_OTSU)
    count, labels, stats, _ = cv2.connectedComponentsWithStats((mask > 0).astype(np.uint8), connectivity=8)
    h, w = img.shape
    background = float(np.median(img[mask == 0])) if np.any(mask == 0) else float(img.max())
    centres, areas = [], []
    for k in range(1, count):
        x, y, bw, bh, area = stats[k]
        if area < 5 or x == 0 or y == 0 or x + bw >= w or y + bh >= h:
            continue
        if area / float(bw * bh) < 0.55 or not 0.6 < bw / bh < 1.67:
            continue  # not round: overlapping beads, wires, edges
        x0, y0, x1, y1 = max(x - 2, 0), max(y - 2, 0), min(x + bw + 2, w), min(y + bh + 2, h)
        own = (labels[y0:y1, x0:x1] == k) | (labels[y0:y1, x0:x1] == 0)
        weight = np.clip(background - img[y0:y1, x0:x1], 0.0, None) * own
        total = weight.sum()
        if total <= 0:
            continue
        vv, uu = np.mgrid[y0:y1, x0:x1]
        centres.append(((weight * uu).sum() / total, (weight * vv).sum() / total))
        areas.append(float(area))
    return np.array(centres, dtype=float).reshape(-1, 2), np.array(areas, dtype=float)


def _dlt(points3, points2) -> np.ndarray:
    """Hartley-normalised DLT: 3x4 P with points2 ~ P [points3; 1]."""
    def normaliser(p):
        mean = p.mean(axis=0)
        scale = np.sqrt(p.shape[1]) / np.mean(np.linalg.norm(p - mean, axis=1))
        T = np.eye(p.shape[1] + 1)
        T[:-1, :-1] *= scale
        T[:-1, -1] = -scale * mean
        return T

    T3, T2 = normaliser(points3), normaliser(points2)
    X = (T3 @ np.column_stack([points3, np.ones(len(points3))]).T).T
    x = (T2 @ np.column_stack([points2, np.ones(len(points2))]).T).T
    rows = []
    for Xi, (u, v, s) in zip(X, x):
        rows.append(np.concatenate([np.zeros(4), -s * Xi, v * Xi]))
        rows.append(np.concatenate([s * Xi, np.zeros(4), -u * Xi]))
    _, _, Vt = np.linalg.svd(np.array(rows))
    P = np.linalg.inv(T2) @ Vt[-1].reshape(3, 4) @ T3
    if np.mean((P @ np.column_stack([points3, np.ones(len(points3))]).T)[2]) < 0:
        P = -P  # beads in front of the source
    return P


def _project(P, points3) -> np.ndarray:
    h = P @ np.column_stack([points3, np.ones(len(points3))]).T
    return (h[:2] / h[2]).T


def _pair(projected, detections, tolerance) -> list[tuple[int, int]]:
    """Mutually nearest (phantom bead, detection) pairs closer than ``tolerance``."""
    tree = cKDTree(detections)
    dist, nearest = tree.query(projected)
    back = cKDTree(projected).query(detections)[1]
    return [(i, int(j)) for i, (d, j) in enumerate(zip(dist, nearest)) if d < tolerance and back[j] == i]


def match_beads(beads: np.ndarray, centres: np.ndarray, areas: np.ndarray) -> list[tuple[int, int]]:
    """(phantom index, detection index) pairs, outliers left out; raises BeadError."""
    if len(centres) < MIN_BEADS:
        raise BeadError(f"too few beads found in the image: {len(centres)} (need at least {MIN_BEADS})")
    typical = np.median(areas)
    marker = int(np.argmax(areas))
    if areas[marker] < MARKER_AREA_RATIO * typical:
        raise BeadError("the marker bead (the phantom's first, larger bead) was not found in the image")
    spacing = float(np.median(cKDTree(centres).query(centres, k=2)[0][:, 1]))
    tolerance = 0.35 * spacing
    others = [k for k in range(len(centres)) if k != marker]
    # phantom triples that span the most volume with the marker bead
    rest = range(1, len(beads))
    triples = sorted(itertools.combinations(rest, 3), key=lambda t: -abs(np.linalg.det(beads[list(t)] - beads[0])))
    triples = triples[:4]
    best, best_count = None, 0
    tree = cKDTree(centres)
    combos = np.array(list(itertools.permutations(others, 3)), dtype=int).reshape(-1, 3)
    homogeneous = np.column_stack([beads, np.ones(len(beads))])
    for triple in triples:
        X = np.column_stack([beads[[0, *triple]], np.ones(4)])
        C = homogeneous @ np.linalg.inv(X)  # (N, 4): the phantom in terms of the 4 chosen beads
        for start in range(0, len(combos), 20000):
            chunk = combos[start:start + 20000]
            corners = np.concatenate([np.repeat(centres[marker][None, None], len(chunk), 0),
                                      centres[chunk]], axis=1)  # (Q, 4, 2)
            projected = np.einsum("nk,qkd->qnd", C, corners)  # affine camera of each hypothesis
            near = tree.query(projected.reshape(-1, 2), distance_upper_bound=tolerance)[0]
            counts = (near < tolerance).reshape(len(chunk), -1).sum(axis=1)
            q = int(np.argmax(counts))
            if counts[q] > best_count:
                best_count = int(counts[q])
                best = np.linalg.solve(X, corners[q]).T  # 2x4: u = A [X; 1]
    if best is None or best_count < MIN_BEADS:
        raise BeadError(f"the beads cannot be matched to the phantom (at most {best_count} of {len(beads)} "
                        "beads agree with one projection)")
    pairs = _pair(np.column_stack([beads, np.ones(len(beads))]) @ best.T, centres, tolerance)
    for _ in range(10):
        if len(pairs) < MIN_BEADS:
            break
        P = _dlt(beads[[i for i, _ in pairs]], centres[[j for _, j in pairs]])
        new = _pair(_project(P, beads), centres, tolerance)
        if new == pairs:
            break
        pairs = new
    if len(pairs) < MIN_BEADS:
        raise BeadError(f"the beads cannot be matched to the phantom: only {len(pairs)} pairs (need {MIN_BEADS})")
    return pairs


@dataclass
class BeadCalibration:
    view: View
    pairs: list[tuple[int, int]]
    residual_px: np.ndarray  # per matched bead
    detections: int

    @property
    def used(self) -> int:
        return len(self.pairs)

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.residual_px**2)))

    @property
    def max_px(self) -> float:
        return float(self.residual_px.max())


def _decompose(P) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    K, R = rq(P[:, :3])
    signs = np.diag(np.sign(np.diag(K)))
    K, R = K @ signs, signs @ R
    t = np.linalg.solve(K, P[:, 3])
    if np.linalg.det(R) < 0:
        R, t = -R, -t
    return K / K[2, 2], R, t


def _refine(K, R, t, points3, points2, square_pixels: bool = True):
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
        return (_project(Kp @ np.column_stack([Rp, tp]), points3) - points2).ravel()

    focal = [np.sqrt(K[0, 0] * K[1, 1])] if square_pixels else [K[0, 0], K[1, 1]]
    start = np.concatenate([focal, [K[0, 2], K[1, 2]], Rotation.from_matrix(R).as_rotvec(), t])
    solution = least_squares(residual, start, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
    return unpack(solution.x)


def calibrate_view(image: np.ndarray, beads, correction=None, pitch: float | None = None,
                   name: str = "", square_pixels: bool = True) -> BeadCalibration:
    """The view that imaged the phantom ``beads`` (N, 3 mm; the first one larger) as ``image``.

    ``correction`` (a ``fluorogui.core.calibration.distortion.Correction``) maps the detected centres to
    ideal pixels first. ``pitch`` (mm) sets the recorded detector pitch (default: DESIGN's).
    ``square_pixels`` fits one focal length (fluoroscopes have square pixels).
    """
    beads = check_phantom(beads)
    centres, areas = detect_beads(image)
    if correction is not None and len(centres):
        centres = correction.correct_points(centres)
    pairs = match_beads(beads, centres, areas)
    points3 = beads[[i for i, _ in pairs]]
    points2 = centres[[j for _, j in pairs]]
    K, R, t = _decompose(_dlt(points3, points2))
    K, R, t = _refine(K, R, t, points3, points2, square_pixels)
    h, w = np.asarray(image).shape[:2]
    try:
        view = View.from_pinhole(K, R, t, (w, h), pitch=pitch or DEFAULT_PITCH_MM, name=name)
    except GeometryError as exc:
        raise BeadError(f"the fitted projection is not a valid view ({exc})") from None
    view.extra.update(source_format="bead calibration", pitch_assumed=pitch is None)
    residual = np.linalg.norm(view.project(points3) - points2, axis=1)
    return BeadCalibration(view, pairs, residual, len(centres))
