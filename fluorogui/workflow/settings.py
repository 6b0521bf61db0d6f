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
    """How tracking predicts, recovers and treats overlapping components."""

    occlusion: bool = True  # mask the other component's projection out of segmentation and matching
    occlusion_margin_px: int = 3  # the mask grows by this much around the other's silhouette
    recover: bool = True  # try other starts when a frame fails its checks
    rotated_start_deg: float = 12.0  # size of the turned starts tried in recovery
    find_near: bool = True  # last resort: search near the prediction (find implants)
    typical_window: int = 15  # matched frames whose residuals set the "typical" residual
    probe: bool = True  # without motion to go by, look for a second orientation that fits as well:
    probe_deg: float = 20.0  # ... this far either way about the least constrained axis ...
    probe_ratio: float = 1.5  # ... for another orientation fitting within this factor: ambiguous

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
    match: MatchSettings = field(default_factory=MatchSettings)
    loop: LoopSettings = field(default_factory=LoopSettings)
    quality: QualityThresholds = field(default_factory=QualityThresholds)
    tracking: TrackingSettings = field(default_factory=TrackingSettings)

    def to_dict(self) -> dict:
        return {"match": self.match.to_dict(), "loop": self.loop.to_dict(), "quality": self.quality.to_dict(),
                "tracking": asdict(self.tracking)}

    @classmethod
    def from_dict(cls, d: dict | None) -> "WorkflowSettings":
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
