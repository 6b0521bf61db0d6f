"""Geometry of one fluoroscope view from an image of a bead phantom of known layout.

Steps (the paper rebuilds each view's projection from such a phantom):

1. ``detect_beads``: dark round blobs (metal beads on a bright field), darkness measured
   against the local bright field (so vignetting does not make blobs of dim corners),
   sub-pixel centres from their darkness-weighted centroid, and their areas.
2. ``match_beads`` (``correspondence``): which blob is which phantom bead, for any phantom
   meeting the file's contract (3D bead centres, the first bead larger): marker-seeded
   affine hypotheses, the best of them refined perspectively by RANSAC over DLT cameras,
   the winner a plausible fluoroscope camera pairing most beads. Detections that no
   phantom bead lands on, and pairs whose residual stands out, are dropped.
3. ``calibrate_view``: DLT (Hartley-normalised), decomposed into ``K [R | t]`` and refined
   as a zero-skew pinhole by least squares on the reprojection error; then converted to
   the view of docs/developer/conventions.rst (source ``-R^T t``, normal ``R^T e_z``,
   ``l = f * pitch``). Reports the reprojection error per bead and the source–intensifier
   distance.

Too few beads, a marker that cannot be told apart, an unmatched or mirrored phantom and a
(nearly) coplanar phantom are refused with a one-line ``BeadError`` saying which.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fluorogui.core.calibration.correspondence import MIN_BEADS, BeadError, match_beads
from fluorogui.core.calibration.pinhole import decompose, dlt, refine
from fluorogui.core.projection.geometry import DEFAULT_PITCH_MM, GeometryError, View

__all__ = ["BeadCalibration", "BeadError", "calibrate_view", "check_phantom", "detect_beads", "match_beads"]

COPLANAR_RATIO = 0.05


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


def _local_background(smooth: np.ndarray) -> np.ndarray:
    """The bright field under the beads: a grey closing with a box wider than any bead (the
    image's 1/16, at least 31 px) removes the dark blobs and follows a smooth field
    (vignetting, a plate seen obliquely); then smoothed, and lowered by the noise's own lift
    so that the field away from the beads sits at zero darkness."""
    h, w = smooth.shape
    size = max(31, (min(h, w) // 16) | 1)
    closed = cv2.morphologyEx(smooth, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_RECT, (size, size)))
    closed = cv2.blur(closed, (size, size))
    lift = closed - smooth
    return closed - float(np.median(lift))


def detect_beads(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (M, 2) in pixels and areas (M,) of the dark round blobs of ``image``.

    Darkness is measured against the local bright field (``_local_background``), relative to
    it, so a vignetted or unevenly lit field does not turn its dim corners into blobs."""
    img = np.asarray(image, dtype=np.float32)
    smooth = cv2.GaussianBlur(img, (0, 0), 1.0)
    field = _local_background(smooth)
    darkness = (field - smooth) / np.maximum(field, 1e-6 * max(float(np.abs(field).max()), 1e-12))
    scaled = cv2.normalize(np.clip(darkness, 0.0, None), None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    _, mask = cv2.threshold(scaled, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    count, labels, stats, _ = cv2.connectedComponentsWithStats((mask > 0).astype(np.uint8), connectivity=8)
    h, w = img.shape
    centres, areas = [], []
    for k in range(1, count):
        x, y, bw, bh, area = stats[k]
        if area < 5 or x == 0 or y == 0 or x + bw >= w or y + bh >= h:
            continue
        if area / float(bw * bh) < 0.55 or not 0.6 < bw / bh < 1.67:
            continue  # not round: overlapping beads, wires, edges
        x0, y0, x1, y1 = max(x - 2, 0), max(y - 2, 0), min(x + bw + 2, w), min(y + bh + 2, h)
        box = labels[y0:y1, x0:x1]
        others = cv2.dilate(((box != k) & (box != 0)).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        own = (box == k) | ((box == 0) & ~others)  # a neighbour's blurred rim is not this bead's darkness
        weight = np.clip(field[y0:y1, x0:x1] - img[y0:y1, x0:x1], 0.0, None) * own
        total = weight.sum()
        if total <= 0:
            continue
        vv, uu = np.mgrid[y0:y1, x0:x1]
        centres.append(((weight * uu).sum() / total, (weight * vv).sum() / total))
        areas.append(float(area))
    return np.array(centres, dtype=float).reshape(-1, 2), np.array(areas, dtype=float)


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


def calibrate_view(image: np.ndarray, beads, *, correction=None, pitch: float | None = None,
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
    h, w = np.asarray(image).shape[:2]
    pairs = match_beads(beads, centres, areas, frame=(w, h))
    points3 = beads[[i for i, _ in pairs]]
    points2 = centres[[j for _, j in pairs]]
    K, R, t = decompose(dlt(points3, points2))
    K, R, t = refine(K, R, t, points3=points3, points2=points2, square_pixels=square_pixels)
    try:
        view = View.from_pinhole(K, R, t, (w, h), pitch=pitch or DEFAULT_PITCH_MM, name=name)
    except GeometryError as exc:
        raise BeadError(f"the fitted projection is not a valid view ({exc})") from None
    view.extra.update(source_format="bead calibration", pitch_assumed=pitch is None)
    residual = np.linalg.norm(view.project(points3) - points2, axis=1)
    return BeadCalibration(view, pairs, residual, len(centres))
