"""What a session and its undo history tell their listeners: every event, with what it
carries, listed here once.

``Session.listeners`` are called as ``listener(event, what)`` with a ``SessionEvent``;
``CommandStack.listeners`` as ``listener(event, entry)`` with a ``HistoryEvent``. Both are
``str`` enums, so a listener written for the plain strings ("pose", "undo") still works.
"""
from __future__ import annotations

import enum


class SessionEvent(str, enum.Enum):
    """A change of the session; ``what`` is given per member."""

    POSE = "pose"  #: a pose record changed: (frame, component)
    OUTLINE = "outline"  #: an outline record changed: (frame, view, component)
    KNEE = "knee"  #: the knee's side ("side"), a component's anatomical frame (its name), or the time base ("time")
    MODEL = "model"  #: a component's mesh file was relinked: the component
    PROJECT = "project"  #: another project was put in the session: None
    SAVED = "saved"  #: the project was saved: the path

    def __str__(self) -> str:
        return self.value


class HistoryEvent(str, enum.Enum):
    """A change of the undo history, after it happened; ``entry`` is the step concerned."""

    PUSH = "push"  #: a step was done and recorded
    MERGE = "merge"  #: a step was merged into the one before (nudges of a pose)
    UNDO = "undo"  #: the step was undone
    REDO = "redo"  #: the step was redone
    CLEAN = "clean"  #: the saved state moved (a save, or none any more): None
    CLEAR = "clear"  #: the history was emptied: None

    def __str__(self) -> str:
        return self.value
