"""The project model: plain dataclasses holding everything a measurement session produces.

The GUI observes these objects and the io layer (``fluorogui.io.project.document``) serialises
them; nothing here touches files. Paths are absolute in memory (the project file stores
them relative to itself). Keys:

* ``records[(frame, view_index, component)]`` - the reviewed image outline of one
  component in one view of one frame;
* ``poses[(frame, component)]`` - the pose (mm, degrees, the convention of docs/developer/conventions.rst) with the
  record of the match that produced it and its status: ``matched`` (every quality check
  passed), ``needs_review`` (a check failed: never to be shown as matched), ``failed``
  (no pose could be found; the pose is the prediction, kept as a start for the user) or
  ``placed`` (set by hand or by *find implants*, not matched). ``reason`` says why a
  frame needs review or failed, in the user's words.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fluorogui.core.projection.geometry import View
from fluorogui.core.status import Status

OutlineKey = tuple[int, int, str]  # (frame, view index, component)

PoseKey = tuple[int, str]  # (frame, component)


def _same_array(a, b) -> bool:
    return np.shape(a) == np.shape(b) and np.array_equal(np.asarray(a), np.asarray(b))


@dataclass(eq=False)
class SplineRecord:
    """A periodic parametric spline through an outline (scipy ``splprep`` tck) and its range.

    ``coefficients`` is (2, n): the u and v control values.
    """

    knots: np.ndarray
    coefficients: np.ndarray
    degree: int = 3
    t_range: tuple[float, float] = (0.0, 1.0)

    def __post_init__(self):
        self.knots = np.asarray(self.knots, dtype=float).reshape(-1)
        self.coefficients = np.atleast_2d(np.asarray(self.coefficients, dtype=float))
        self.degree = int(self.degree)
        self.t_range = (float(self.t_range[0]), float(self.t_range[1]))

    def __eq__(self, other) -> bool:
        if not isinstance(other, SplineRecord):
            return NotImplemented
        return (
            _same_array(self.knots, other.knots)
            and _same_array(self.coefficients, other.coefficients)
            and self.degree == other.degree
            and self.t_range == other.t_range
        )


@dataclass(eq=False)
class OutlineRecord:
    """An edited image outline: ordered points (K, 2) in pixels, its spline, review state,
    and optionally how much each point counts in a match (``weights``, K positive numbers:
    the rim refinement's ``core.outlines.profile_fit.precision_weights``; None: all alike)."""

    points: np.ndarray
    spline: SplineRecord | None = None
    reviewed: bool = False
    weights: np.ndarray | None = None

    def __post_init__(self):
        self.points = np.asarray(self.points, dtype=float).reshape(-1, 2)
        self.reviewed = bool(self.reviewed)
        if self.weights is not None:
            self.weights = np.asarray(self.weights, dtype=float).reshape(-1)
            if len(self.weights) != len(self.points) or not np.all(np.isfinite(self.weights) & (self.weights > 0)):
                raise ValueError(f"an outline of {len(self.points)} points needs as many positive weights, "
                                 f"got {len(self.weights)}")

    def __eq__(self, other) -> bool:
        if not isinstance(other, OutlineRecord):
            return NotImplemented
        return (_same_array(self.points, other.points) and self.spline == other.spline
                and self.reviewed == other.reviewed and _same_array(self.weights, other.weights))


@dataclass
class MatchRecord:
    """How a pose was found: the objective (Eq. 5) in mm, per-view mean distances, effort."""

    objective_mm: float
    per_view_mean_mm: list[float]
    calls: int
    seconds: float
    converged: bool
    method: str
    settings: dict = field(default_factory=dict)
    quality: dict = field(default_factory=dict)  # ``fluorogui.core.matching.quality.Quality.to_dict()``
    history: list[float] = field(default_factory=list)  # the objective (mm) after every accepted step

    @classmethod
    def from_result(cls, result, quality: dict | None = None) -> "MatchRecord":
        """The record of a ``fluorogui.core.matching.matcher.MatchResult`` (its stored fields)."""
        return cls(
            objective_mm=float(result.objective_mm),
            per_view_mean_mm=[float(v) for v in result.per_view_mean_mm],
            calls=int(result.calls),
            seconds=float(result.seconds),
            converged=bool(result.converged),
            method=str(result.method),
            settings=dict(result.settings),
            quality=dict(quality or {}),
            history=[round(float(v), 6) for v in result.history],
        )


@dataclass(eq=False)
class PoseRecord:
    """A component's pose in one frame (x, y, z mm; alpha, beta, gamma deg), its match,
    its ``Status`` (by default ``matched`` with a converged match record,
    else ``placed``), why it needs review, and whether the user has accepted it."""

    pose: np.ndarray
    match: MatchRecord | None = None
    reviewed: bool = False
    status: str = ""
    reason: str = ""

    def __post_init__(self):
        self.pose = np.asarray(self.pose, dtype=float).reshape(6)
        self.reviewed = bool(self.reviewed)
        if not self.status:
            self.status = default_status(self.match)
        try:
            self.status = Status(self.status)
        except ValueError:
            known = ", ".join(s.value for s in Status)
            raise ValueError(f"unknown pose status {self.status!r} (use {known})") from None
        self.reason = str(self.reason)

    @property
    def is_matched(self) -> bool:
        """A pose that may be shown as matched: every check passed, or the user accepted it."""
        return self.reviewed or self.status == Status.MATCHED

    @property
    def needs_review(self) -> bool:
        return not self.reviewed and self.status in (Status.NEEDS_REVIEW, Status.FAILED)

    def __eq__(self, other) -> bool:
        if not isinstance(other, PoseRecord):
            return NotImplemented
        return (_same_array(self.pose, other.pose) and self.match == other.match and self.reviewed == other.reviewed
                and self.status == other.status and self.reason == other.reason)


def default_status(match: MatchRecord | None) -> str:
    """The status of a pose record that does not state one (files of schema 2 and older)."""
    if match is None:
        return Status.PLACED
    return Status.MATCHED if match.converged else Status.NEEDS_REVIEW


@dataclass(eq=False)
class ModelEntry:
    """An implant component: its mesh file, sampling density and local frame (4x4, mm)."""

    component: str
    mesh_path: Path
    point_density: int = 15000
    local_frame: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self):
        self.mesh_path = Path(self.mesh_path)
        self.point_density = int(self.point_density)
        self.local_frame = np.asarray(self.local_frame, dtype=float).reshape(4, 4)

    def __eq__(self, other) -> bool:
        if not isinstance(other, ModelEntry):
            return NotImplemented
        return (
            self.component == other.component
            and self.mesh_path == other.mesh_path
            and self.point_density == other.point_density
            and _same_array(self.local_frame, other.local_frame)
        )


@dataclass
class ImageSequence:
    """The image files of one view, in frame order."""

    paths: list[Path] = field(default_factory=list)

    def __post_init__(self):
        self.paths = [Path(p) for p in self.paths]


@dataclass(eq=False)
class Project:
    """Everything a session needs to be reopened: views, images, models, outlines, poses."""

    views: list[View] = field(default_factory=list)
    sequences: list[ImageSequence] = field(default_factory=list)
    frames: list[int] = field(default_factory=list)
    models: list[ModelEntry] = field(default_factory=list)
    records: dict[OutlineKey, OutlineRecord] = field(default_factory=dict)
    poses: dict[PoseKey, PoseRecord] = field(default_factory=dict)
    settings: dict = field(default_factory=dict)

    def model(self, component: str) -> ModelEntry | None:
        """The model entry of a component, or None."""
        return next((m for m in self.models if m.component == component), None)

    def __eq__(self, other) -> bool:
        if not isinstance(other, Project):
            return NotImplemented
        return (
            [v.to_dict() for v in self.views] == [v.to_dict() for v in other.views]
            and self.sequences == other.sequences
            and list(self.frames) == list(other.frames)
            and self.models == other.models
            and self.records == other.records
            and self.poses == other.poses
            and self.settings == other.settings
        )
