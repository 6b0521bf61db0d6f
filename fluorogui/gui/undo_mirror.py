"""The Qt undo stack as a mirror of a session's plain ``CommandStack``.

The session's history is the one record of what was done (the command line and scripts
use it without Qt). The app needs a ``QUndoStack`` for its Undo / Redo actions, their
texts and the window's modified flag, so ``HistoryMirror`` keeps one QUndoCommand per
history entry: pushed when the history records an entry (its first redo does nothing,
the history already did the change), and its undo / redo ask the history to undo /
redo. When the history moves by itself (a script, a test), the mirror follows without
calling back. Macros are single history entries, so they are single mirror commands.
"""
from __future__ import annotations

from PySide6.QtCore import QObject
from PySide6.QtGui import QUndoCommand, QUndoStack

from fluorogui.workflow.history import CommandStack


class _MirrorCommand(QUndoCommand):
    """One history entry on the Qt stack."""

    def __init__(self, mirror: "HistoryMirror", text: str) -> None:
        super().__init__(text)
        self._mirror = mirror
        self._done = False

    def redo(self) -> None:
        if not self._done:  # pushed after the history did the change
            self._done = True
            return
        self._mirror._replay(redo=True)

    def undo(self) -> None:
        self._mirror._replay(redo=False)


class HistoryMirror(QUndoStack):
    """A QUndoStack that shows ``history`` and undoes / redoes through it."""

    def __init__(self, history: CommandStack, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.history = history
        self._replaying = False  # the Qt stack asked the history to move
        self._following = False  # the history moved by itself; the Qt stack follows
        history.listeners.append(self._heard)

    def detach(self) -> None:
        if self._heard in self.history.listeners:
            self.history.listeners.remove(self._heard)

    def _replay(self, redo: bool) -> None:
        if self._following:
            return
        self._replaying = True
        try:
            if redo:
                self.history.redo()
            else:
                self.history.undo()
        finally:
            self._replaying = False

    def _heard(self, event: str, entry) -> None:
        if self._replaying:
            return
        if event == "push":
            self.push(_MirrorCommand(self, entry.text))
        elif event == "merge":
            top = self.command(self.index() - 1)
            if top is not None:
                top.setText(entry.text)
        elif event in ("undo", "redo"):
            self._following = True
            try:
                (self.undo if event == "undo" else self.redo)()
            finally:
                self._following = False
        elif event == "clear":
            self.clear()
        elif event == "clean":
            if self.history.dirty:
                self.resetClean()
            else:
                self.setClean()
