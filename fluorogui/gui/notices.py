"""How the main window's presenters speak to the user: a line in the status bar, a warning
dialog, a yes / no question, and the widget their dialogs belong to.

A presenter is given a ``Notices`` instead of the window: it needs these four things of
it, not its widgets. The last warning's text stays in ``last_error`` (scripts, the
snapshot tool and tests read it as ``window.last_error``)."""
from __future__ import annotations

from PySide6.QtWidgets import QMainWindow, QMessageBox, QWidget


class Notices:
    """The status bar, warnings and questions of a main window."""

    def __init__(self, window: QMainWindow) -> None:
        self._window = window
        self.last_error = ""

    @property
    def parent_widget(self) -> QWidget:
        """The widget dialogs are opened over (the main window)."""
        return self._window

    def status(self, text: str, timeout_ms: int = 0) -> None:
        """A message in the status bar (for ``timeout_ms``, 0: until the next one)."""
        self._window.statusBar().showMessage(text, timeout_ms)

    def status_text(self) -> str:
        return self._window.statusBar().currentMessage()

    def error(self, message: str) -> None:
        """A problem said in the status bar and kept in ``last_error``, without a dialog."""
        self.last_error = message
        self.status(message, 10000)

    def warn(self, title: str, message: str) -> None:
        """A warning dialog; its text stays in the status bar and in ``last_error``."""
        self.error(message)
        QMessageBox.warning(self._window, title, message)

    def ask(self, title: str, question: str) -> bool:
        """A yes / no question (No is the default): True for Yes."""
        answer = QMessageBox.question(self._window, title, question,
                                      QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
                                      QMessageBox.StandardButton.No)
        return answer == QMessageBox.StandardButton.Yes
