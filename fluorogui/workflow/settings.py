"""The workflow's settings: matcher, segmentation loop, quality limits and tracking, kept in
the project (``project.settings["workflow"]``) so a session reopens with what it used.
Each part is a section of ``fluorogui.core.settings`` (``workflow.match`` ...), registered
there with its record and its check, which is where a project file's values are checked."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from fluorogui.core.matching.loop import LoopSettings
from fluorogui.core.matching.problem import MatchSettings
from fluorogui.core.matching.quality import QualityThresholds
from fluorogui.core.settings import TrackingSettings

SETTINGS_KEY = "workflow"


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

__all__ = ["SETTINGS_KEY", "TrackingSettings", "WorkflowSettings"]
