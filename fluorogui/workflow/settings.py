"""The workflow's settings: matcher, segmentation loop, quality limits and tracking, kept in
the project (``project.settings["workflow"]``) so a session reopens with what it used."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from fluorogui.core.matching.loop import LoopSettings
from fluorogui.core.matching.problem import MatchSettings
from fluorogui.core.matching.quality import QualityThresholds

SETTINGS_KEY = "workflow"


@dataclass
class TrackingSettings:
    """How tracking predicts, recovers and treats overlapping components.

    Attributes
    ----------
    occlusion : bool
        Mask the other component's projection out of segmentation and matching.
    occlusion_margin_px : int
        The mask grows by this much around the other's silhouette.
    recover : bool
        Try other starts when a frame fails its checks.
    rotated_start_deg : float
        Size of the turned starts tried in recovery.
    find_near : bool
        Last resort: search near the prediction (*find implants*).
    typical_window : int
        Matched frames whose residuals set the "typical" residual of the checks.
    probe : bool
        Without motion to go by, look for a second orientation that fits as well ...
    probe_deg : float
        ... this far either way about the least constrained axis ...
    probe_ratio : float
        ... and call the pose ambiguous when one fits within this factor.
    max_seconds : float
        When a component's first start in a frame fails its checks, recovery tries other
        starts until this long after the match began: then it stops (a running start at its
        next check) and the best result so far, flagged ``needs_review`` (or ``failed``),
        says so in its reason; 0: no limit. The first start and the probe always run to
        their end. A recovered real frame takes under a second; a start far off took
        minutes (every recovery start fitting the rim models again).
    """

    occlusion: bool = True  # mask the other component's projection out of segmentation and matching
    occlusion_margin_px: int = 3  # the mask grows by this much around the other's silhouette
    recover: bool = True  # try other starts when a frame fails its checks
    rotated_start_deg: float = 12.0  # size of the turned starts tried in recovery
    find_near: bool = True  # last resort: search near the prediction (find implants)
    typical_window: int = 15  # matched frames whose residuals set the "typical" residual
    probe: bool = True  # without motion to go by, look for a second orientation that fits as well:
    probe_deg: float = 20.0  # ... this far either way about the least constrained axis ...
    probe_ratio: float = 1.5  # ... for another orientation fitting within this factor: ambiguous
    max_seconds: float = 20.0  # recovery stops this long after a component's match began, flagged (0: none)

    @classmethod
    def from_dict(cls, d: dict | None) -> "TrackingSettings":
        d = d or {}
        out = cls()
        for f in fields(cls):
            if f.name in d:
                setattr(out, f.name, type(getattr(out, f.name))(d[f.name]))
        return out


@dataclass
class WorkflowSettings:
    """Everything a match, a track and their checks are set by; kept in the project.

    Read a copy with :attr:`Session.settings <fluorogui.workflow.session.Session.settings>`,
    change it, and give it back with :meth:`Session.set_settings
    <fluorogui.workflow.session.Session.set_settings>`.

    Parameters
    ----------
    match : fluorogui.core.matching.problem.MatchSettings
        The matcher: ``method`` (``"fast"`` or ``"paper"``), outline and model points,
        convergence, robust loss, restarts.
    loop : fluorogui.core.matching.loop.LoopSettings
        The segment-match loop: passes, when it has settled, search bands, and ``rim``
        (``"auto"``, ``"on"``, ``"off"``).
    quality : fluorogui.core.matching.quality.QualityThresholds
        The limits of the quality checks.
    tracking : TrackingSettings
        Prediction, recovery and occlusion in tracking.

    Examples
    --------
    >>> from fluorogui import WorkflowSettings
    >>> settings = WorkflowSettings()
    >>> settings.match.method, settings.loop.rim, settings.quality.max_view_mm
    ('fast', 'auto', 0.6)
    >>> settings.loop.rim = "off"
    >>> WorkflowSettings.from_dict(settings.to_dict()).loop.rim
    'off'
    """

    match: MatchSettings = field(default_factory=MatchSettings)
    loop: LoopSettings = field(default_factory=LoopSettings)
    quality: QualityThresholds = field(default_factory=QualityThresholds)
    tracking: TrackingSettings = field(default_factory=TrackingSettings)

    def to_dict(self) -> dict:
        """Plain JSON-ready data, as the project stores it."""
        return {"match": self.match.to_dict(), "loop": self.loop.to_dict(), "quality": self.quality.to_dict(),
                "tracking": asdict(self.tracking)}

    @classmethod
    def from_dict(cls, d: dict | None) -> "WorkflowSettings":
        """Settings from :meth:`to_dict`'s data; missing or unknown entries take their defaults."""
        d = d if isinstance(d, dict) else {}
        match = MatchSettings()
        raw = d.get("match") if isinstance(d.get("match"), dict) else {}
        for f in fields(MatchSettings):
            if f.name in raw and raw[f.name] is not None:
                value = raw[f.name]
                setattr(match, f.name, tuple(value) if isinstance(getattr(match, f.name), tuple) else value)
        return cls(match, LoopSettings.from_dict(d.get("loop") if isinstance(d.get("loop"), dict) else None),
                   QualityThresholds.from_dict(d.get("quality") if isinstance(d.get("quality"), dict) else None),
                   TrackingSettings.from_dict(d.get("tracking") if isinstance(d.get("tracking"), dict) else None))
