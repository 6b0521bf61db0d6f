"""Start the desktop app: QApplication, theme, log file, crash handler, main window, then
a project (or a folder to import), a recovered session or the built-in demo (with the
guided tour on its first run)."""
from __future__ import annotations

import json
import logging
import os
import sys
import time
from pathlib import Path

from PySide6.QtCore import QSettings, QTimer
from PySide6.QtWidgets import QApplication

from fluorogui import __version__
from fluorogui.gui import theme
from fluorogui.gui.binding import reference_leak
from fluorogui.gui.main_window import MainWindow

__all__ = ["MainWindow", "run_app", "make_application"]

#: set (to anything) to start, show the first session, print one JSON line and quit: the
#: standalone build's start-up check (packaging/build.py --check)
SMOKE_ENV = "FLUOROGUI_SMOKE_TEST"


def make_application() -> QApplication:
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("fluorogui")
    app.setOrganizationName("fluorogui")
    app.setApplicationVersion(__version__)
    app.setDesktopFileName("fluorogui")
    app.setWindowIcon(theme.icon("app"))
    theme.apply_theme(app, str(QSettings("fluorogui", "fluorogui").value("theme", "system")))
    return app


def open_start_path(window: MainWindow, path: str | Path) -> bool:
    """Open what the app was started with: a project file, or a folder to import (the
    import dialog filled from it). A path that is missing, unreadable or not a project
    gets one clear dialog; the window then stays usable and says what to do."""
    path = Path(path)
    if path.is_dir() and path.suffix.lower() != ".fluoro":
        window.open_paths([path])
        return True
    if not path.exists():
        window.warn("Cannot open project", f"{path}: no such file. Open another one with File → Open (Ctrl+O).")
        return False
    if path.is_file() and not os.access(path, os.R_OK):
        window.warn("Cannot open project", f"{path}: not readable (permission denied).")
        return False
    return window.open_project(path, ask=False)


def run_app(path: str | Path | None = None) -> int:
    """Start the desktop app, optionally opening a project file or importing a folder;
    return the exit code.

    Without a file, an autosaved session left by a crash is offered first; otherwise the
    demo session opens so a new user can try the whole loop at once."""
    t0 = time.perf_counter()
    from fluorogui.logs import record_fatal_errors, setup_logging

    setup_logging()
    record_fatal_errors()
    app = make_application()
    binding_defect = reference_leak()
    if binding_defect:
        logging.getLogger("fluorogui").error(binding_defect)
    window = MainWindow()
    smoke = bool(os.environ.get(SMOKE_ENV))
    if not smoke:
        from fluorogui.gui.dialogs.crash import install_crash_handler

        install_crash_handler(window)
    window.show()

    def first_session():
        demo = False
        if path is not None:
            open_start_path(window, path)
        elif smoke or not window.offer_recovery():
            demo = window.open_demo(ask=False)
        window.fit_images()
        window.statusBar().showMessage(
            window.statusBar().currentMessage() or f"Ready in {time.perf_counter() - t0:.1f} s", 10000)
        if smoke:
            print(json.dumps({"started_s": round(time.perf_counter() - t0, 2), "title": window.windowTitle(),
                              "frames": len(window.controller.frames), "version": __version__}), flush=True)
            window.controller.session.history.set_clean()
            QTimer.singleShot(0, window.close)
        elif demo:
            from fluorogui.gui.dialogs.tour import start_tour

            start_tour(window)
        if binding_defect and not smoke:
            window.warn("This installation's Qt may crash fluorogui", binding_defect + ". Your work is journalled "
                        "as you go, and offered back after a crash.")

    QTimer.singleShot(0, first_session)
    return app.exec()
