"""The intensifier's field of view in an image: where outlines can be seen at all.

One function for the matcher's checks, *find implants* and tracking: ``field_of_view``
finds the bright disc at half the resolution of a 1024-pixel image and returns it at full
resolution, shrunk by a margin. ``image_unit`` and ``to_unit_float`` are the image-scale
helpers it shares with the shape search.
"""
from __future__ import annotations

import cv2
import numpy as np

from fluorogui.core.outlines.quantile import tail_percentile


def image_unit(shape) -> float:
    """Pixel lengths in this module are for 1024-pixel images; this is the factor for an
    image of ``shape`` (the same field of view in more or fewer pixels)."""
    return max(shape[:2]) / 1024.0


def to_unit_float(image: np.ndarray) -> np.ndarray:
    """Grey image as float32 in [0, 1] (8/16-bit or float; colour converted): the image
    itself when it already is one (read it, do not write to it)."""
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img.astype(np.float32), cv2.COLOR_BGR2GRAY)
    img = img.astype(np.float32, copy=False)
    lo, hi = float(img.min()), float(img.max())
    if lo < 0.0 or hi > 1.0:
        img = (img - lo) / max(hi - lo, 1e-12)
    return img


def field_of_view(image: np.ndarray, margin_px: int = 15) -> np.ndarray:
    """The intensifier's field of view (bool, full resolution), found at half the
    resolution of a 1024-pixel image (``intensifier_disc``), shrunk by ``margin_px``
    (of such a half-size image)."""
    scale = 0.5 / image_unit(np.shape(image))
    half = cv2.resize(to_unit_float(image), None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    fov = intensifier_disc(np.round(half * 255).astype(np.uint8), margin_px=margin_px)
    return cv2.resize(fov.astype(np.uint8), np.shape(image)[1::-1], interpolation=cv2.INTER_NEAREST) > 0


def intensifier_disc(image: np.ndarray, border_level: float | None = None, margin_px: int = 12) -> np.ndarray:
    """Boolean mask of the intensifier's field of view (the bright disc), shrunk by ``margin_px``.

    The black frame is what is darker than ``border_level`` and connected to the image
    edges; the field of view is the convex hull of the rest (the disc is convex, so
    components touching its rim are not cut off). The default level is a quarter of the
    way from the frame's grey (the median of a strip along the image border) up to the
    darkest grey in the middle of the image (its 0.5th percentile), at least 4: a frame
    that is not quite black (noise, an offset) is still found."""
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), 1.5)
    h, w = img.shape
    if border_level is None:
        centre = tail_percentile(img[h // 4: 3 * h // 4, w // 4: 3 * w // 4], 0.5)  # = np.percentile
        k = max(2, min(h, w) // 50)
        frame = float(np.median(np.r_[img[:k].ravel(), img[-k:].ravel(), img[:, :k].ravel(), img[:, -k:].ravel()]))
        frame = min(frame, centre)  # no darker frame: the field of view fills the image
        border_level = max(4.0, frame + 0.25 * (centre - frame))
    dark = (img <= border_level).astype(np.uint8)
    n, labels = cv2.connectedComponents(dark, connectivity=8)
    edge_labels = np.unique(np.r_[labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    edge_labels = edge_labels[edge_labels > 0]
    outside = np.isin(labels, edge_labels) if len(edge_labels) else np.zeros_like(dark, bool)
    inside = (~outside).astype(np.uint8)
    inside = cv2.morphologyEx(inside, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
    contours, _ = cv2.findContours(inside, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return np.zeros((h, w), bool)
    hull = cv2.convexHull(np.vstack(contours))  # the hull of the outer boundaries is that of every pixel
    fov = np.zeros((h, w), np.uint8)
    cv2.fillConvexPoly(fov, hull, 1)
    if margin_px > 0:
        fov = cv2.erode(fov, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1,) * 2))
    return fov > 0
