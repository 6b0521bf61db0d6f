"""Undoable changes to a project as plain commands, and the stack that keeps them.

Every edit of a session (a pose, an outline, a review flag) is a ``Command`` holding the
record before and after; applying it stores one or the other through a setter. The
``CommandStack`` keeps the history with macros (several commands undone as one), merging
of repeated small steps (nudges of one pose) and a clean index ("saved here"). It knows
nothing of Qt: the desktop app's QUndoStack only mirrors it (see ``listeners``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from fluorogui.workflow.session.events import HistoryEvent

Setter = Callable[[Any, Any], None]  # setter(key, record or None)


@dataclass
class Command:
    """One change: ``setter(key, after)`` does it, ``setter(key, before)`` undoes it."""

    text: str
    key: Any
    before: Any
    after: Any
    setter: Setter
    merge_id: str | None = None  # consecutive commands with the same id and key merge

    def redo(self) -> None:
        self.setter(self.key, self.after)

    def undo(self) -> None:
        self.setter(self.key, self.before)


@dataclass
class Macro:
    """Commands done and undone together (e.g. a match: two outlines and a pose)."""

    text: str
    commands: list = field(default_factory=list)
    merge_id: str | None = None
    key: Any = None

    def redo(self) -> None:
        for c in self.commands:
            c.redo()

    def undo(self) -> None:
        for c in reversed(self.commands):
            c.undo()


class CommandStack:
    """Linear undo history. ``listeners`` are called as ``listener(event, entry)`` with a
    ``workflow.session.events.HistoryEvent`` after the change."""

    def __init__(self) -> None:
        self._entries: list = []
        self._index = 0  # entries[:index] are done
        self._clean: int | None = 0
        self._open: list[Macro] = []
        self.listeners: list[Callable[[str, Any], None]] = []

    # -- state ---------------------------------------------------------------------------------
    @property
    def index(self) -> int:
        return self._index

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def dirty(self) -> bool:
        return self._clean != self._index

    def can_undo(self) -> bool:
        return self._index > 0 and not self._open

    def can_redo(self) -> bool:
        return self._index < len(self._entries) and not self._open

    def undo_text(self) -> str:
        return self._entries[self._index - 1].text if self.can_undo() else ""

    def redo_text(self) -> str:
        return self._entries[self._index].text if self.can_redo() else ""

    # -- changes -------------------------------------------------------------------------------
    def push(self, command: Command) -> None:
        """Do ``command`` and record it (inside an open macro, as part of the macro)."""
        command.redo()
        if self._open:
            self._open[-1].commands.append(command)
            return
        top = self._entries[self._index - 1] if self._index > 0 else None
        if (command.merge_id is not None and top is not None and self._clean != self._index
                and isinstance(top, Command) and top.merge_id == command.merge_id and top.key == command.key):
            top.after = command.after
            self._notify(HistoryEvent.MERGE, top)
            return
        self._record(command)

    def begin_macro(self, text: str) -> None:
        self._open.append(Macro(text))

    def end_macro(self) -> None:
        macro = self._open.pop()
        if self._open:
            self._open[-1].commands.append(macro)
        elif macro.commands:
            self._record(macro)

    def undo(self) -> None:
        if not self.can_undo():
            return
        self._index -= 1
        entry = self._entries[self._index]
        entry.undo()
        self._notify(HistoryEvent.UNDO, entry)

    def redo(self) -> None:
        if not self.can_redo():
            return
        entry = self._entries[self._index]
        entry.redo()
        self._index += 1
        self._notify(HistoryEvent.REDO, entry)

    def set_clean(self) -> None:
        """Mark the current state as saved."""
        self._clean = self._index
        self._notify(HistoryEvent.CLEAN, None)

    def reset_clean(self) -> None:
        """No state is saved (e.g. a new project never written): always dirty."""
        self._clean = None
        self._notify(HistoryEvent.CLEAN, None)

    def clear(self) -> None:
        self._entries.clear()
        self._index = 0
        self._clean = 0
        self._open.clear()
        self._notify(HistoryEvent.CLEAR, None)

    # -- helpers -------------------------------------------------------------------------------
    def _record(self, entry) -> None:
        del self._entries[self._index:]
        if self._clean is not None and self._clean > self._index:
            self._clean = None  # the saved state can no longer be reached
        self._entries.append(entry)
        self._index += 1
        self._notify(HistoryEvent.PUSH, entry)

    def _notify(self, event: str, entry) -> None:
        for listener in list(self.listeners):
            listener(event, entry)
