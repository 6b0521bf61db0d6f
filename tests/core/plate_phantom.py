"""Synthetic perforated plates seen through a known image-intensifier distortion (for tests)."""
from __future__ import annotations

import numpy as np


class KnownDistortion:
    """Pincushion (r -> r (1 + k r^2)) plus S-distortion (a turn growing as r^2) about the centre.

    ``apply`` maps ideal pixels to distorted ones; ``invert`` the other way (by iteration).
    Its Jacobian at the centre is the identity, the convention the plate fit uses.
    """

    def __init__(self, size=(512, 512), pincushion_px=6.0, s_turn_px=2.5):
        self.centre = (np.asarray(size, dtype=float) - 1) / 2.0
        self.radius = float(max(size)) / 2.0
        self.k = pincushion_px / self.radius**3
        self.s = s_turn_px / self.radius

    def apply(self, uv) -> np.ndarray:
        q = np.atleast_2d(np.asarray(uv, dtype=float)) - self.centre
        r2 = (q**2).sum(axis=1)
        q = q * (1.0 + self.k * r2)[:, None]
        phi = self.s * r2 / self.radius**2
        c, s = np.cos(phi), np.sin(phi)
        return np.column_stack([c * q[:, 0] - s * q[:, 1], s * q[:, 0] + c * q[:, 1]]) + self.centre

    def invert(self, uv, iterations: int = 40) -> np.ndarray:
        target = np.atleast_2d(np.asarray(uv, dtype=float))
        x = target.copy()
        for _ in range(iterations):
            x -= self.apply(x) - target
        return x

    def distort_image(self, image: np.ndarray) -> np.ndarray:
        import cv2

        h, w = image.shape
        vv, uu = np.mgrid[0:h, 0:w].astype(float)
        src = self.invert(np.column_stack([uu.ravel(), vv.ravel()])).reshape(h, w, 2).astype(np.float32)
        return cv2.remap(image.astype(np.float32), src[..., 0], src[..., 1], cv2.INTER_CUBIC,
                         borderMode=cv2.BORDER_REPLICATE)


def lattice(grid: str, spacing_px: float, turn_deg: float = 3.0):
    """Basis vectors (columns) of a square or hexagonal lattice, turned by ``turn_deg``."""
    t = np.radians(turn_deg)
    a = spacing_px * np.array([np.cos(t), np.sin(t)])
    angle = np.radians(90.0 if grid == "square" else 60.0)
    b = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]) @ a
    return np.column_stack([a, b])


def plate_image(distortion: KnownDistortion, size=(384, 384), grid="square", spacing_px=14.0, hole_px=3.5,
                supersample=3, noise_sd=0.0, rng=None, offset=(0.3, -0.2)) -> tuple[np.ndarray, np.ndarray]:
    """A distorted plate image (dark plate 0.2, bright holes 0.9), and the distorted true hole centres."""
    w, h = size
    basis = lattice(grid, spacing_px)
    origin = distortion.centre + np.asarray(offset)
    inverse = np.linalg.inv(basis)
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    total = np.zeros((h, w))
    vv, uu = np.mgrid[0:h, 0:w].astype(float)
    # ideal position of each pixel centre, and the inverse map's Jacobian for the sub-samples
    centre_ideal = distortion.invert(np.column_stack([uu.ravel(), vv.ravel()]), iterations=15).reshape(h, w, 2)
    d_dv, d_du = np.gradient(centre_ideal, axis=(0, 1))
    for dv in sub:
        for du in sub:
            pts = np.column_stack([(uu + du).ravel(), (vv + dv).ravel()])
            ideal = (centre_ideal + du * d_du + dv * d_dv).reshape(-1, 2)
            frac = (ideal - origin) @ inverse.T
            best = np.full(len(pts), np.inf)
            for fi in (np.floor, np.ceil):
                for fj in (np.floor, np.ceil):
                    site = np.column_stack([fi(frac[:, 0]), fj(frac[:, 1])]) @ basis.T + origin
                    best = np.minimum(best, np.linalg.norm(ideal - site, axis=1))
            total += (best <= hole_px).reshape(h, w)
    image = 0.2 + 0.7 * total / supersample**2
    if noise_sd:
        image = image + (rng or np.random.default_rng(0)).normal(0, noise_sd, image.shape)
    n = int(max(size) / spacing_px) + 3
    ij = np.array([(i, j) for i in range(-n, n + 1) for j in range(-n, n + 1)], dtype=float)
    sites = ij @ basis.T + origin
    distorted = distortion.apply(sites)
    inside = np.all((distorted > hole_px + 2) & (distorted < np.array(size) - hole_px - 2), axis=1)
    return np.clip(image, 0, 1).astype(np.float32), distorted[inside]
