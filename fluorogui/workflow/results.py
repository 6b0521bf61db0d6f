"""What a match, a search or a tracked frame produces, and how it becomes project records.

``FrameResult`` is the one result type of the workflow: the app, the command line
(``--json`` lines) and scripts all receive it. Its ``status`` is ``matched`` only when
every quality check passed; otherwise ``needs_review`` (a pose was found but a check
failed) or ``failed`` (no pose; ``pose`` is then the prediction, a start for the user).
``kept`` marks a frame whose stored result was left as it was (accepted by the user, or
already matched when a run resumes).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fluorogui.core.matching.problem import MatchResult
from fluorogui.core.matching.quality import Quality
from fluorogui.core.records import MatchRecord, PoseRecord
from fluorogui.core.status import Status

__all__ = ["FrameResult"]



@dataclass
class FrameResult:
    """What matching one component in one frame produced: the one result type of the workflow.

    :meth:`Session.match <fluorogui.workflow.session.Session.match>` returns them,
    :meth:`Session.track <fluorogui.workflow.session.Session.track>` yields them, and the
    command line prints them (:meth:`to_json`).

    Attributes
    ----------
    frame : int
        The frame number.
    component : str
        ``"femoral"``, ``"tibial"`` or another model's name.
    pose : numpy.ndarray or None
        ``(x, y, z, alpha, beta, gamma)``, mm and degrees; for a ``failed`` frame the
        prediction (a start for the user); None when there is not even that.
    status : fluorogui.core.status.Status
        ``matched`` only when every quality check passed; ``needs_review`` when a pose was
        found but a check failed; ``failed`` when no pose was found. Compares equal to its
        string value.
    reason : str
        Why it needs review or failed, in plain words; empty when matched.
    match : fluorogui.core.matching.problem.MatchResult or None
        The matcher's result: objective, residual per view, calls, the pose's SDs.
    quality : fluorogui.core.matching.quality.Quality or None
        The quality checks' measurements.
    outlines : list of numpy.ndarray or None
        Per view, the automatic outline (pixels) to store; None where a reviewed one was used.
    seconds : float
        Wall time of the frame's work for this component.
    kept : bool
        The stored result was left as it was (accepted by the user, or already matched
        when a run resumed); nothing else here is new.
    attempts : int
        Starts tried (1 when the prediction was right at once).
    recovered : str
        How a lost frame was recovered (``"last pose"``, ``"rotated start"``, ``"find near"``),
        or empty.

    Examples
    --------
    >>> from fluorogui import FrameResult
    >>> r = FrameResult(frame=3, component="tibial", pose=None, status="failed",
    ...                 reason="view 2: no image for frame 3")
    >>> r.is_matched, r.sd
    (False, None)
    >>> r.to_json()["status"]
    'failed'
    """

    frame: int
    component: str
    pose: np.ndarray | None
    status: str
    reason: str = ""
    match: MatchResult | None = None
    quality: Quality | None = None
    outlines: list[np.ndarray | None] | None = None  # automatic outlines to store, per view
    seconds: float = 0.0
    kept: bool = False
    attempts: int = 0  # starts tried (1 when the prediction was right at once)
    recovered: str = ""  # how a lost frame was recovered ("last pose", "rotated start", "find near")
    rim_models: list | None = field(default=None, repr=False)  # per view, the core.outlines.rim models it used
    #: per view, the component's rim models once its judgement has settled (the project keeps
    #: them, so later runs need not fit them again); None before
    rim_settled: list | None = field(default=None, repr=False)
    #: the checks it failed (``core.matching.quality.CHECKS``, or "ambiguous", "segmentation",
    #: "match", "find", "image"): what a measurement of each check's precision counts
    failed: list[str] = field(default_factory=list)
    #: per view, the automatic outline's point weights (``core.outlines.profile_fit.precision_weights``;
    #: None: all alike)
    outline_weights: list | None = field(default=None, repr=False)

    @property
    def is_matched(self) -> bool:
        """True when the status is ``matched`` (every quality check passed)."""
        return self.status == Status.MATCHED

    @property
    def sd(self) -> list[float | None] | None:
        """The pose's six standard deviations (mm, degrees), rounded to 1e-6.

        None when the match gave none; an entry is None where the outlines fix nothing
        in that direction.
        """
        if self.match is None or self.match.sd is None:
            return None
        return [round(float(v), 6) if np.isfinite(v) else None for v in self.match.sd]

    def record(self) -> PoseRecord | None:
        """The pose record :meth:`Session.store <fluorogui.workflow.session.Session.store>` keeps.

        Returns
        -------
        fluorogui.core.records.PoseRecord or None
            The pose with its status, reason and match record (quality checks and SDs
            included); None when there is no pose at all.
        """
        if self.pose is None:
            return None
        match = None
        if self.match is not None:
            quality = self.quality.to_dict() if self.quality else {}
            if self.match.sd is not None:  # the pose's standard deviations (mm, deg), kept with its checks
                quality["sd"] = self.sd
            if self.match.cov_body is not None:  # the body's whole covariance, for the knee's SDs
                quality["cov_body"] = [[round(float(v), 9) for v in row] for row in self.match.cov_body]
            match = MatchRecord.from_result(self.match, quality)
        return PoseRecord(np.asarray(self.pose, dtype=float), match, reviewed=False, status=self.status,
                          reason=self.reason)

    def to_json(self) -> dict:
        """The command line's per-frame JSON object (``fluorogui track --json``): a contract.

        Returns
        -------
        dict
            ``frame``, ``component``, ``pose`` (6 numbers or None), ``objective_mm``,
            ``per_view_mean_mm``, ``converged`` (the status is ``matched``), ``sd``,
            ``status``, ``reason`` and ``seconds``; numbers rounded to 1e-6 (seconds 1e-4).
        """
        m = self.match
        return {
            "frame": int(self.frame),
            "component": self.component,
            "pose": None if self.pose is None else [round(float(v), 6) for v in self.pose],
            "objective_mm": None if m is None else round(float(m.objective_mm), 6),
            "per_view_mean_mm": None if m is None else [round(float(v), 6) for v in m.per_view_mean_mm],
            "converged": bool(m is not None and m.converged),
            "sd": self.sd,
            "status": self.status,
            "reason": self.reason,
            "seconds": round(float(self.seconds), 4),
        }
