"""Problems in the user's words: what went wrong, where (frame, view, component) and what
to do. Engine errors carry short technical texts; these turn them into sentences such
as "view 1: the tibial outline could not be traced, it crosses itself — edit it or
re-run Find implants", never a class name."""
from __future__ import annotations

import re

from fluorogui.core.matching.loop import SegmentationError

_PLAIN = (
    (re.compile(r"crosses itself"), "it crosses itself"),
    (re.compile(r"has (\d+) points; at least 4"), r"only \1 edge points were found"),
    (re.compile(r"no edges near|no edge with the expected polarity|no edge contour lies along|too few edge points"),
     "too few image edges lie along the model"),
    (re.compile(r"outside the image"), "the model lies outside the image"),
    (re.compile(r"behind the X-ray source"), "part of the model lies behind the X-ray source"),
    (re.compile(r"no silhouette"), "the model has no outline from this source"),
)


def plain(reason: str) -> str:
    """A short engine message as a clause a user understands."""
    for pattern, text in _PLAIN:
        found = pattern.search(reason)
        if found:
            return found.expand(text)
    return reason


def segmentation_failed(component: str, error: SegmentationError) -> str:
    return (f"view {error.view + 1}: the {component} outline could not be traced, {plain(error.reason)} "
            "— edit it or re-run Find implants")


def match_failed(component: str, error: Exception) -> str:
    if isinstance(error, SegmentationError):
        return segmentation_failed(component, error)
    return f"the {component} component could not be matched: {plain(str(error))}"


def out_of_time(seconds: float, limit: float) -> str:
    return (f"stopped after {seconds:.0f} s: recovery may take {limit:g} s (the tracking setting max_seconds); "
            "check the start pose, or give outlines")


def image_missing(view: int, problem: str) -> str:
    return f"view {view + 1}: {problem}"


def where(frame: int, component: str | None = None) -> str:
    return f"frame {frame}" + (f", {component}" if component else "")


SINGLE_PLANE_NOTE = ("single-plane session: translation along the X-ray beam (out of the image plane) is the "
                     "weak direction; expect errors there several times larger than in the image plane")


def view_count_note(n_views: int) -> str | None:
    """What a user must know about a session's geometry (one view: the weak direction)."""
    return SINGLE_PLANE_NOTE if n_views == 1 else None


def rim_note(settings: dict | None) -> str:
    """Which views' automatic outlines the loop moved for the metal's rim (``rim_refined``
    in a match's settings), in words; empty when none."""
    refined = [k + 1 for k, r in enumerate((settings or {}).get("rim_refined") or []) if r]
    if not refined:
        return ""
    views = " and ".join(str(k) for k in refined)
    return f"outline moved for the metal's soft rim in view{'s' if len(refined) > 1 else ''} {views}"
