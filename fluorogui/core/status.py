"""The status of a component's pose in a frame: the one vocabulary of the engine's checks,
the project file, the command line's JSON and the app's timeline."""
from __future__ import annotations

import enum


class Status(str, enum.Enum):
    """``matched``: every quality check passed; ``needs_review``: a pose was found but a
    check failed (never to be shown as matched); ``failed``: no pose could be found (the
    pose kept is the prediction, a start for the user); ``placed``: set by hand or by
    *find implants*, not matched. A ``str`` whose value is what files and JSON hold."""

    PLACED = "placed"
    MATCHED = "matched"
    NEEDS_REVIEW = "needs_review"
    FAILED = "failed"

    def __str__(self) -> str:
        return self.value
