"""Start the desktop app: QApplication, theme, main window, then a project, a recovered
session or the built-in demo."""
from __future__ import annotations

import sys
import time
from pathlib import Path

from PySide6.QtCore import QSettings, QTimer
from PySide6.QtWidgets import QApplication

from fluorogui import __version__
from fluorogui.gui import theme
from fluorogui.gui.main_window import MainWindow

__all__ = ["MainWindow", "run_app", "make_application"]


def make_application() -> QApplication:
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("fluorogui")
    app.setOrganizationName("fluorogui")
    app.setApplicationVersion(__version__)
    app.setDesktopFileName("fluorogui")
    app.setWindowIcon(theme.icon("app"))
    theme.apply_theme(app, str(QSettings("fluorogui", "fluorogui").value("theme", "system")))
    return app


def run_app(path: str | Path | None = None) -> int:
    """Start the desktop app, optionally opening a project file; return the exit code.

    Without a file, an autosaved session left by a crash is offered first; otherwise the
    demo session opens so a new user can try the whole loop at once."""
    t0 = time.perf_counter()
    app = make_application()
    window = MainWindow()
    window.show()

    def first_session():
        if path is not None:
            window.open_project(path, ask=False)
        elif not window.offer_recovery():
            window.open_demo(ask=False)
        window.fit_images()
        window.statusBar().showMessage(
            window.statusBar().currentMessage() or f"Ready in {time.perf_counter() - t0:.1f} s", 10000)

    QTimer.singleShot(0, first_session)
    return app.exec()
