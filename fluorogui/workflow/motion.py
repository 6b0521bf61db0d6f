"""Predicting a component's pose in the next frame from the frames matched so far.

Constant velocity about the model centroid: the centroid moves and the body turns at the
rate of the last two matched frames (per frame number, so gaps in the frame numbers are
handled), extrapolated at most twice as far as those two frames lie apart so that a
long gap does not fling the prediction away. With one matched frame the prediction is
that frame's pose. A frame before every matched one is predicted backward the same way,
from the two earliest matched frames (tracking back to the start).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from fluorogui.core.projection.pose import angles_from_matrix, rotation_matrix


class MotionModel:
    """Matched poses of one component by frame number, and predictions from them."""

    def __init__(self, centroid: np.ndarray) -> None:
        self.centroid = np.asarray(centroid, dtype=float)
        self.frames: list[int] = []
        self.poses: list[np.ndarray] = []

    def add(self, frame: int, pose) -> None:
        """Record a matched (or accepted) pose; keeps the frames sorted."""
        frame = int(frame)
        if frame in self.frames:
            i = self.frames.index(frame)
            self.poses[i] = np.asarray(pose, dtype=float).copy()
            return
        i = int(np.searchsorted(self.frames, frame))
        self.frames.insert(i, frame)
        self.poses.insert(i, np.asarray(pose, dtype=float).copy())

    def __len__(self) -> int:
        return len(self.frames)

    def last(self, before: int | None = None) -> np.ndarray | None:
        """The latest recorded pose (before frame ``before`` when given)."""
        idx = [i for i, f in enumerate(self.frames) if before is None or f < before]
        return self.poses[idx[-1]].copy() if idx else None

    def predict(self, frame: int) -> np.ndarray | None:
        """The pose expected at ``frame`` from the two latest recorded frames before it, or,
        when none is before it, from the two earliest after it (backward)."""
        idx = [i for i, f in enumerate(self.frames) if f < frame]
        if not idx:
            idx = [i for i, f in enumerate(self.frames) if f > frame][:2][::-1]  # nearest last
        if not idx:
            return None
        if len(idx) == 1:
            return self.poses[idx[-1]].copy()
        (f1, p1), (f2, p2) = [(self.frames[i], self.poses[i]) for i in idx[-2:]]
        steps = min(abs(frame - f2), 2 * abs(f2 - f1)) / abs(f2 - f1)
        R1, R2 = rotation_matrix(*p1[3:]), rotation_matrix(*p2[3:])
        c1, c2 = R1 @ self.centroid + p1[:3], R2 @ self.centroid + p2[:3]
        turn = Rotation.from_matrix(R2 @ R1.T).as_rotvec()
        R = Rotation.from_rotvec(turn * steps).as_matrix() @ R2
        c = c2 + (c2 - c1) * steps
        return np.array([*(c - R @ self.centroid), *angles_from_matrix(R)])
