"""Undo and Redo bound to the session's own history (``fluorogui.workflow.session.history``).

There is no second stack: the actions (declared in ``gui.layout.actions``, with their
keys, and given to ``UndoActions``) call ``history.undo()`` / ``history.redo()``, and their enabled state and texts
("Undo Match femoral") follow the history's listener events (push, merge, undo, redo,
clear, clean), whoever moved it - the user, a script or a test. The window's modified
flag follows the same events through the controller's ``dirty_changed``.
"""
from __future__ import annotations

from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QAction

from fluorogui.workflow.session.events import HistoryEvent
from fluorogui.workflow.session.history import CommandStack


class UndoActions(QObject):
    """The Undo and Redo actions of one history, kept in step with it."""

    #: a step was undone or redone, by anyone: ("undo" or "redo", the step's text)
    stepped = Signal(str, str)

    def __init__(self, history: CommandStack, undo_action: QAction, redo_action: QAction) -> None:
        """The actions' texts now ("&Undo", "&Redo") are the prefixes of the step's text."""
        super().__init__(undo_action)
        self.history = history
        self.undo_action, self.redo_action = undo_action, redo_action
        self._prefixes = (undo_action.text(), redo_action.text())
        undo_action.triggered.connect(lambda: self.history.undo())
        redo_action.triggered.connect(lambda: self.history.redo())
        history.listeners.append(self._heard)
        self.refresh()

    def detach(self) -> None:
        """Stop following the history (the window is closing)."""
        if self._heard in self.history.listeners:
            self.history.listeners.remove(self._heard)

    def _heard(self, event: str, entry) -> None:
        self.refresh()
        if event in (HistoryEvent.UNDO, HistoryEvent.REDO):
            self.stepped.emit(str(event), str(getattr(entry, "text", "") or ""))

    def refresh(self) -> None:
        """Enabled state and texts from the history as it is now."""
        history, (undo, redo) = self.history, self._prefixes
        for action, prefix, can, text in ((self.undo_action, undo, history.can_undo(), history.undo_text()),
                                          (self.redo_action, redo, history.can_redo(), history.redo_text())):
            action.setEnabled(can)
            action.setText(f"{prefix} {text}" if can and text else prefix)
