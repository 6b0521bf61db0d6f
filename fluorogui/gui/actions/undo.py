"""Undo and Redo bound to the session's own history (``fluorogui.workflow.history``).

There is no second stack: the actions call ``history.undo()`` / ``history.redo()``, and
their enabled state and texts ("Undo Match femoral") follow the history's listener events
(push, merge, undo, redo, clear, clean), whoever moved it - the user, a script or a test.
The window's modified flag follows the same events through the controller's
``dirty_changed``.

Their keys are the platform's standard ones plus those users bring from elsewhere
(Ctrl+Shift+Z, which the guides give, and Ctrl+Y for Redo), each bound once: the same
key bound twice to one action is an ambiguous shortcut, which Qt ignores.
"""
from __future__ import annotations

from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QAction, QKeySequence

from fluorogui.workflow.events import HistoryEvent
from fluorogui.workflow.history import CommandStack


def standard_keys(standard: QKeySequence.StandardKey, *extra: str) -> list[QKeySequence]:
    """``extra`` keys first, then the platform's bindings of ``standard``, each once."""
    keys = [QKeySequence(k) for k in extra] + list(QKeySequence.keyBindings(standard))
    unique = dict.fromkeys(k.toString(QKeySequence.SequenceFormat.PortableText) for k in keys if not k.isEmpty())
    return [QKeySequence(k) for k in unique]


class UndoActions(QObject):
    """The Undo and Redo actions of one history."""

    #: a step was undone or redone, by anyone: ("undo" or "redo", the step's text)
    stepped = Signal(str, str)

    def __init__(self, history: CommandStack, parent: QObject) -> None:
        super().__init__(parent)
        self.history = history
        self.undo_action = QAction("&Undo", parent)
        self.undo_action.setShortcuts(standard_keys(QKeySequence.StandardKey.Undo, "Ctrl+Z"))
        self.undo_action.triggered.connect(lambda: self.history.undo())
        self.redo_action = QAction("&Redo", parent)
        self.redo_action.setShortcuts(standard_keys(QKeySequence.StandardKey.Redo, "Ctrl+Shift+Z", "Ctrl+Y"))
        self.redo_action.triggered.connect(lambda: self.history.redo())
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
        history = self.history
        for action, prefix, can, text in ((self.undo_action, "&Undo", history.can_undo(), history.undo_text()),
                                          (self.redo_action, "&Redo", history.can_redo(), history.redo_text())):
            action.setEnabled(can)
            action.setText(f"{prefix} {text}" if can and text else prefix)
