"""Undo and Redo bound to the session's own history (``fluorogui.workflow.history``).

There is no second stack: the actions call ``history.undo()`` / ``history.redo()``, and
their enabled state and texts ("Undo Match femoral") follow the history's listener events
(push, merge, undo, redo, clear, clean), whoever moved it - the user, a script or a test.
The window's modified flag follows the same events through the controller's
``dirty_changed``.
"""
from __future__ import annotations

from PySide6.QtCore import QObject
from PySide6.QtGui import QAction, QKeySequence

from fluorogui.workflow.history import CommandStack


class UndoActions(QObject):
    """The Undo and Redo actions of one history."""

    def __init__(self, history: CommandStack, parent: QObject) -> None:
        super().__init__(parent)
        self.history = history
        self.undo_action = QAction("&Undo", parent)
        self.undo_action.setShortcut(QKeySequence.StandardKey.Undo)
        self.undo_action.triggered.connect(lambda: self.history.undo())
        self.redo_action = QAction("&Redo", parent)
        self.redo_action.setShortcuts([QKeySequence("Ctrl+Shift+Z"), QKeySequence.StandardKey.Redo])
        self.redo_action.triggered.connect(lambda: self.history.redo())
        history.listeners.append(self._heard)
        self.refresh()

    def detach(self) -> None:
        """Stop following the history (the window is closing)."""
        if self._heard in self.history.listeners:
            self.history.listeners.remove(self._heard)

    def _heard(self, _event: str, _entry) -> None:
        self.refresh()

    def refresh(self) -> None:
        """Enabled state and texts from the history as it is now."""
        history = self.history
        for action, prefix, can, text in ((self.undo_action, "&Undo", history.can_undo(), history.undo_text()),
                                          (self.redo_action, "&Redo", history.can_redo(), history.redo_text())):
            action.setEnabled(can)
            action.setText(f"{prefix} {text}" if can and text else prefix)
