"""The sections of a project's settings (``project.settings``), each registered here once:
its key, the module that owns it (reads and writes it), its typed record or kind, its
default and its check. ``fluorogui.io`` checks a project's settings against this registry
when it loads one (``check_sections``) without importing the workflow, and the workflow's
records (``WorkflowSettings``) are made of the sections registered under ``workflow.``.

Sections with a check refuse a file whose value the owner could not use (one message
naming the field); the others are read leniently by their owner (what is damaged falls
back to its default), so they have no check. Plain data; nothing here writes a file.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Callable

from fluorogui.core.matching.loop import LoopSettings
from fluorogui.core.matching.problem import MatchSettings
from fluorogui.core.matching.quality import QualityThresholds


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


def shown(value) -> str:
    """A value as a message names it: ``an object``, ``a list of 3``, or its repr (40 characters)."""
    if isinstance(value, (dict, list)):
        return "an object" if isinstance(value, dict) else f"a list of {len(value)}"
    return repr(value)[:40]


def check_record(values: dict, record: type, where: str) -> None:
    """Raise ValueError naming ``where.key`` when a stored setting does not have the kind of
    the record's default (number, whole number, true/false, text, list of numbers), is not
    finite, or is negative (every engine setting is a size, a count or a limit), or when
    the record's own ``from_dict`` refuses it (an unknown rim mode). Unknown keys pass."""
    default_record = record()
    for key, default in ((f.name, getattr(default_record, f.name)) for f in fields(record)):
        if key not in values:
            continue
        value, name = values[key], f"field '{where}.{key}'"
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if isinstance(default, bool):
            ok, kind = isinstance(value, bool), "true or false"
        elif isinstance(default, int) or (default is None and key.endswith("points")):
            ok = (value is None and default is None) or (isinstance(value, int) and not isinstance(value, bool)
                                                          and 0 <= value <= 10**9)
            kind = "a whole number from 0 to 10^9"
        elif isinstance(default, float) or default is None:
            ok = (value is None and default is None) or (number and math.isfinite(value) and 0 <= value <= 1e9)
            kind = "a finite number from 0 to 10^9"
        elif isinstance(default, str):
            ok, kind = isinstance(value, str) and len(value) <= 100, "a short text"
        elif isinstance(default, tuple):
            ok = isinstance(value, list) and len(value) == len(default) and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
            kind = f"a list of {len(default)} numbers"
        else:
            continue
        if not ok:
            raise ValueError(f"{name} must be {kind}, not {shown(value)}")
    if hasattr(record, "from_dict"):
        try:
            record.from_dict(values)
        except ValueError as exc:
            raise ValueError(f"field '{where}': {exc}") from None


def check_object(value, where: str) -> None:
    """Raise ValueError unless ``value`` is a JSON object."""
    if not isinstance(value, dict):
        raise ValueError(f"field '{where}' must be an object, not {shown(value)}")


@dataclass(frozen=True)
class Section:
    """One section of ``project.settings``.

    Attributes
    ----------
    key : str
        Where it is kept: a key of ``project.settings``, or ``parent.key`` one level down
        (``workflow.match``).
    owner : str
        The module that reads and writes it.
    record : type or None
        Its typed record (a dataclass of settings), or None for plain JSON data.
    check : callable or None
        ``check(value, where)`` raises ValueError naming the field when a file holds a
        value the owner cannot use; None when the owner reads it leniently.
    about : str
        What it holds, in a few words.
    """

    key: str
    owner: str
    record: type | None = None
    check: Callable[[object, str], None] | None = None
    about: str = ""

    def default(self):
        """A new default value: the record's defaults, else an empty object."""
        return self.record() if self.record is not None else {}


SECTIONS: dict[str, Section] = {}


def register(section: Section) -> Section:
    """Add a section (a key registered twice is a programming error)."""
    if section.key in SECTIONS:
        raise ValueError(f"the settings section {section.key!r} is registered twice")
    SECTIONS[section.key] = section
    return section


def _typed(record: type) -> Callable[[object, str], None]:
    def check(value, where: str) -> None:
        check_object(value, where)
        check_record(value, record, where)
    return check


def _workflow(value, where: str) -> None:
    check_object(value, where)
    for name, part in value.items():
        check_object(part, f"{where}.{name}")


for _section in (
    Section("gui", "fluorogui.gui.controller", check=check_object,
            about="the desktop app's view: zoom, contrast, panels, per project"),
    Section("workflow", "fluorogui.workflow.settings", check=_workflow,
            about="the matcher, loop, quality and tracking settings (WorkflowSettings)"),
    Section("workflow.match", "fluorogui.core.matching.problem", MatchSettings, _typed(MatchSettings),
            "the matcher: method, points, convergence, robust loss, restarts"),
    Section("workflow.loop", "fluorogui.core.matching.loop", LoopSettings, _typed(LoopSettings),
            "the segment-match loop: passes, bands, rim refinement"),
    Section("workflow.quality", "fluorogui.core.matching.quality", QualityThresholds, _typed(QualityThresholds),
            "the limits of the quality checks"),
    Section("workflow.tracking", "fluorogui.workflow.tracking", TrackingSettings, _typed(TrackingSettings),
            "prediction, recovery and occlusion in tracking"),
    Section("kinematics", "fluorogui.workflow.session.knee",
            about="the knee's side and user anatomical frames (a broken frame falls back to the default)"),
    Section("rim_models", "fluorogui.workflow.session.work",
            about="each component's rim models per view (a damaged entry is judged again)"),
    Section("time", "fluorogui.io.motion_files", about="the frame rate and where it came from (unusable: none)"),
    Section("demo", "fluorogui.simulation.demo", about="the demo's recipe (the app marks an unsaved demo with true)"),
    Section("demo_truth", "fluorogui.simulation.demo", about="the demo's true poses"),
    Section("truth", "fluorogui.simulation.knee_bend", about="a generated knee bend's true poses"),
    Section("synthetic", "fluorogui.simulation.knee_bend", about="a generated knee bend's recipe"),
):
    register(_section)


ABSENT = object()


def stored(settings: dict, key: str, absent=ABSENT):
    """The value a section has in ``settings`` (``parent.key`` looked up one level down), or
    ``absent`` when it has none."""
    parent, _, child = key.partition(".")
    value = settings.get(parent, absent) if isinstance(settings, dict) else absent
    if child:
        value = value.get(child, absent) if isinstance(value, dict) else absent
    return value


def check_sections(settings: dict) -> None:
    """Raise ValueError naming the field when a registered section of ``settings`` (a
    project's) holds what its owner cannot use; sections not registered pass."""
    for section in SECTIONS.values():
        value = stored(settings, section.key)
        if value is not ABSENT and section.check is not None:
            section.check(value, f"settings.{section.key}")
