"""What a match works on and what it gives: the settings of both methods, the problem (a
mesh, the views, the image outlines and the occlusion masks), the result, and the
centroid parametrisation the optimisers and the uncertainty share.

Poses in and out follow the DESIGN.md convention (mm, degrees). The objective is in mm
on the intensifier plane (pixels times pixel pitch), as in the paper.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Callable, Sequence

import numpy as np

from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh, sample_surface
from fluorogui.core.projection.pose import angles_from_matrix, rotation_matrix

ProgressCallback = Callable[[int, float, np.ndarray], None]


@dataclass


class MatchSettings:
    method: str = "fast"  # "fast" or "paper"
    outline_points: int | None = None  # paper: N equally spaced (default 60); fast: None = one per `spacing_px`
    outline_spacing_mm: float | None = None  # paper alternative: one point every d mm on the intensifier
    model_points: int = 15000  # paper: size of the point cloud
    max_calls: int = 800
    xtol: float = 0.0005  # mm and degrees: stop when the next step changes every variable less (fast: see _below_noise)
    fd_step: float = 0.1  # paper: finite-difference step (mm, deg); the paper does not give one
    spacing_px: float = 2.0  # fast: spacing of image outline points when outline_points is None
    # fast: spacing of model outline points (outline_points None); 2 px apart, the points kept
    # shift enough from pose to pose to make the cost ripple (tests/core/test_cost_smoothness.py)
    model_spacing_px: float = 1.0
    huber_px: float = 2.0  # fast: Huber threshold of the robust loss
    symmetric: bool = True  # fast: add image-to-model residuals
    skip_gaps: bool = True  # fast: no residuals on chords the outline draws across gaps
    centre_first: bool = True  # fast: first shift the model so the outline centroids meet
    starts: int = 1  # independent starts (the given one plus perturbed ones); the best is kept
    restart_sd: tuple[float, float] = (5.0, 5.0)  # mm, deg for the extra starts
    seed: int = 0

    def to_dict(self) -> dict:
        return asdict(self)

    def validate(self) -> None:
        """Refuse settings the matcher cannot work with (ValueError naming the option)."""
        if self.outline_points is not None and self.outline_points < MIN_OUTLINE_POINTS:
            raise ValueError(f"--outline-points {self.outline_points}: at least {MIN_OUTLINE_POINTS} outline "
                             "points per view are needed to fix six pose variables")
        if self.model_points < 100:
            raise ValueError(f"--points {self.model_points}: a point model needs at least 100 points")
        if self.starts < 1 or self.max_calls < 1:
            raise ValueError("starts and max_calls must be positive")


#: fewest outline points per view a match accepts (six unknowns, with room for noise)
MIN_OUTLINE_POINTS = 8


@dataclass(frozen=True, kw_only=True)
class MatchResult:
    pose: np.ndarray
    objective_mm: float
    per_view_mean_mm: list[float]
    calls: int
    seconds: float
    converged: bool
    method: str
    settings: dict
    message: str = ""
    history: list[float] = field(default_factory=list)
    #: fast method: the 6x6 Gauss-Newton matrix at the result, in the matcher's variables
    #: (centroid shift mm, rotation vector x model radius mm); says how well each direction
    #: of motion is pinned down by the outlines
    normal_matrix: np.ndarray | None = field(default=None, repr=False)
    #: fast method: the model outline (pixels) per view at the result, about 1 px apart
    outlines_px: list | None = field(default=None, repr=False)
    #: standard deviations of the six pose variables (mm, deg) from the Gauss-Newton
    #: covariance at the result (``pose_covariance``); inf where the outlines fix nothing
    sd: list[float] | None = None
    #: the same for the body's own motion: its centroid (world x, y, z, mm) and its turn about
    #: its own model axes x, y, z (deg), free of the Euler angles' coupling
    sd_body: list[float] | None = None
    #: ... and their whole 6x6 covariance (mm, deg), for what is computed from the pose
    #: (the knee's kinematics); None where the outlines fix nothing in some direction
    cov_body: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: did the optimiser itself stop by its criterion (``converged`` also needs the checks)
    optimiser_converged: bool = False
    #: the checks of its own evidence it failed (``quality.MATCH_CHECKS`` names; ``judge_match``)
    failed: list[str] = field(default_factory=list)
    #: fast method: (pose, evaluation) at the result, reused by the covariance and the loop
    evaluation: tuple | None = field(default=None, repr=False, compare=False)
    #: from images (``matching.loop.segment_and_match``): the outline splines the result
    #: was matched on, per view ...
    splines: list | None = field(default=None, repr=False)
    #: ... the automatic outlines among them (pixels; None for a view's given outline, and
    #: None overall when every outline was given) ...
    image_outlines: list | None = field(default=None, repr=False)
    #: ... their points' weights (per view, None: all alike; ``outlines.rim``) ...
    outline_weights: list | None = field(default=None, repr=False)
    #: ... and the segment -> match passes it took (1 when matched once on given outlines)
    passes: int = 1

    def weakest_rotation_axis(self) -> np.ndarray | None:
        """Unit axis (world) of the turn the outlines constrain least, translation free to
        follow (smallest eigenvalue of the rotation block's Schur complement)."""
        H = self.normal_matrix
        if H is None:
            return None
        try:
            S = H[3:, 3:] - H[3:, :3] @ np.linalg.solve(H[:3, :3], H[:3, 3:])
        except np.linalg.LinAlgError:
            return None
        return np.linalg.eigh(S)[1][:, 0]

    def to_dict(self) -> dict:
        return {
            "pose": [float(v) for v in self.pose],
            "objective_mm": float(self.objective_mm),
            "per_view_mean_mm": [float(v) for v in self.per_view_mean_mm],
            "calls": int(self.calls),
            "seconds": float(self.seconds),
            "converged": bool(self.converged),
            "method": self.method,
            "message": self.message,
            "sd": None if self.sd is None else [float(v) for v in self.sd],
            "settings": self.settings,
        }


@dataclass


class MatchProblem:
    """One component in one frame: its mesh, the views and the image outline splines.

    ``occluded`` optionally gives, per view, a boolean image mask (or None) of where
    another component hides this one's outline: the fast method leaves out the model and
    image outline points that fall there (their image edges belong to the other
    component, or are missing)."""

    mesh: PreparedMesh
    views: Sequence[View]
    splines: Sequence  # OutlineSpline per view
    occluded: Sequence | None = None
    _cloud: dict = field(default_factory=dict, repr=False)

    def occluder(self, view_index: int) -> np.ndarray | None:
        if self.occluded is None or view_index >= len(self.occluded):
            return None
        return self.occluded[view_index]

    def cloud(self, n: int, seed: int = 0) -> np.ndarray:
        if (n, seed) not in self._cloud:
            self._cloud[(n, seed)] = sample_surface(self.mesh.vertices, self.mesh.faces, n, seed)
        return self._cloud[(n, seed)]


# -- centroid parametrisation ---------------------------------------------------------------


# -- centroid parametrisation ---------------------------------------------------------------


def _to_state(pose: np.ndarray, centroid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R = rotation_matrix(*pose[3:])
    return R, R @ centroid + pose[:3]


def _to_pose(R: np.ndarray, c: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    return np.array([*(c - R @ centroid), *angles_from_matrix(R)])


# -- occlusion masks -----------------------------------------------------------------------------
#: a view keeps all its outline points when fewer than this many are outside the occluded area
MIN_VISIBLE_POINTS = 8


def mask_at(mask: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """A boolean image's value at points (K, 2) in pixels (nearest pixel); beyond the image
    the mask goes on as its border pixels are (a field-of-view mask hides what lies beyond
    the image, an occlusion mask does not)."""
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    h, w = mask.shape
    uv = np.nan_to_num(uv, nan=-1.0, posinf=1e9, neginf=-1e9)
    col = np.minimum(np.maximum(np.round(uv[:, 0]), 0), w - 1).astype(int)  # (np.clip's wrapper: slower)
    row = np.minimum(np.maximum(np.round(uv[:, 1]), 0), h - 1).astype(int)
    return mask[row, col].astype(bool)


def visible_points(mask: np.ndarray | None, uv: np.ndarray) -> np.ndarray:
    """True for points (K, 2) in pixels that a boolean ``mask`` does not cover (beyond the
    image as its border pixels are); all True without a mask or when almost nothing is left."""
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    if mask is None or len(uv) == 0:
        return np.ones(len(uv), dtype=bool)
    visible = ~mask_at(mask, uv)
    return visible if visible.sum() >= MIN_VISIBLE_POINTS else np.ones(len(uv), dtype=bool)
