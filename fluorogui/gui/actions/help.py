"""The Help menu of the main window: the quick-start page (shipped in
``fluorogui/resources/quickstart.html``), the complete keyboard and mouse shortcut list,
and About (version and the log file's path).

``HelpActions`` is given the widget its dialogs belong to, the window's actions (the
shortcut list is read from them, so a new action with a shortcut is listed without editing
this file) and how to start the guided tour. Its actions are declared in
``gui.layout.actions``.
"""
from __future__ import annotations

import html
from collections.abc import Callable

from PySide6.QtCore import QObject, Qt
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QDialog, QDialogButtonBox, QMessageBox, QTextBrowser, QVBoxLayout, QWidget

from fluorogui import __version__
from fluorogui.logs import log_file_path
from fluorogui.resources import resource_path

#: gestures and keys that are not actions (the image panels and the 3D panel handle them)
MOUSE_AND_PANEL_KEYS = (
    ("Zoom at the cursor", "Mouse wheel"),
    ("Pan an image", "Middle-drag (or drag with Navigate)"),
    ("Window / level", "Right-drag"),
    ("Add a contour to the outline", "Shift+click with Pick contour"),
    ("Delete the selected (or nearest) outline point", "Delete or Backspace in an image"),
    ("Drop the selection or gesture in an image", "Esc in an image"),
    ("Frames in the timeline", "Left / Right, Home / End"),
    ("Nudge the model", "Ctrl+arrows, Ctrl+PgUp / Ctrl+PgDown"),
    ("Turn the model", "Ctrl+Shift+arrows, Ctrl+Shift+PgUp / PgDown"),
)


class HelpActions(QObject):
    """The Help menu's actions of a main window: quick start, shortcuts, the guided tour, About."""

    def __init__(self, parent: QWidget, *, window_actions: Callable[[], list[QAction]],
                 start_tour: Callable[[], object]) -> None:
        """``window_actions``: the actions of the window, in the order they were added;
        ``start_tour``: shows the guided tour and returns it."""
        super().__init__(parent)
        self.dialog_parent = parent
        self._window_actions = window_actions
        self._start_tour = start_tour

    def show_tour(self):
        return self._start_tour()

    def shortcut_rows(self) -> list[tuple[str, str]]:
        """(what, keys) for every action with a shortcut, then the mouse and panel keys."""
        rows, seen = [], set()
        for action in self._window_actions():
            keys = list(dict.fromkeys(k.toString(QKeySequence.SequenceFormat.NativeText)
                                      for k in action.shortcuts() if not k.isEmpty()))  # once each
            name = action.text().replace("&", "").rstrip("…").strip()
            if not keys or name.startswith(("Move x", "Move y", "Move z", "Turn alpha", "Turn beta", "Turn gamma")):
                continue
            if (name, keys[0]) in seen:
                continue
            seen.add((name, keys[0]))
            rows.append((name, " or ".join(keys)))
        return rows + list(MOUSE_AND_PANEL_KEYS)

    def shortcuts_html(self) -> str:
        cells = "".join(f"<tr><td style='padding:1px 14px 1px 0'><b>{html.escape(keys)}</b></td>"
                        f"<td>{html.escape(name)}</td></tr>" for name, keys in self.shortcut_rows())
        return f"<table cellspacing='0'>{cells}</table>"

    def _html_dialog(self, title: str, body: str, name: str) -> QDialog:
        dialog = QDialog(self.dialog_parent)
        dialog.setObjectName(name)
        dialog.setWindowTitle(title)
        browser = QTextBrowser(dialog)
        browser.setOpenExternalLinks(True)
        browser.setHtml(body)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close, dialog)
        buttons.rejected.connect(dialog.reject)
        layout = QVBoxLayout(dialog)
        layout.addWidget(browser)
        layout.addWidget(buttons)
        dialog.resize(560, 600)
        dialog.browser = browser
        return dialog

    def show_shortcuts(self) -> QDialog:
        dialog = self._html_dialog("Keyboard shortcuts", self.shortcuts_html(), "shortcutsDialog")
        dialog.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        dialog.show()
        return dialog

    def quick_start_html(self) -> str:
        page = resource_path("quickstart.html").read_text(encoding="utf-8")
        return page.replace("<!--SHORTCUTS-->", self.shortcuts_html())

    def show_quick_start(self) -> QDialog:
        dialog = self._html_dialog("Quick start", self.quick_start_html(), "quickStartDialog")
        dialog.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        dialog.show()
        return dialog

    def about_text(self) -> str:
        from fluorogui.gui.actions.files import app_data_dir

        return (f"<h3>fluorogui {html.escape(__version__)}</h3>"
                "<p>Pose of total-knee-replacement implants from two fluoroscopic views "
                "(after Tsai et al., J Biomech Eng 2006).</p>"
                f"<p>Log file: <code>{html.escape(str(log_file_path()))}</code><br>"
                f"Data folder (demo, autosave): <code>{html.escape(str(app_data_dir()))}</code></p>")

    def show_about(self) -> None:
        QMessageBox.about(self.dialog_parent, "About fluorogui", self.about_text())
