"""Rotations spread evenly over SO(3), the orientations *find implants* tries first."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def orientation_grid(n: int) -> np.ndarray:
    """(n, 3, 3) rotations spread evenly over SO(3) (super-Fibonacci spiral, Alexa 2022)."""
    phi = np.sqrt(2.0)
    psi = 1.533751168755204288118041
    s = np.arange(n) + 0.5
    r = np.sqrt(s / n)
    big = np.sqrt(1.0 - s / n)
    a = 2 * np.pi * s / phi
    b = 2 * np.pi * s / psi
    q = np.column_stack([r * np.sin(a), r * np.cos(a), big * np.sin(b), big * np.cos(b)])  # (x, y, z, w)
    return Rotation.from_quat(q).as_matrix()
