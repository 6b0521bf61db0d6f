"""The desktop app's crash handler: an uncaught exception (in a slot, a timer, an event
handler) is logged with its traceback, the session is autosaved, and a dialog says what
happened, where the autosave and the log file are, with *Copy details*.

Installed by ``fluorogui.gui.app.run_app`` only (tests keep pytest-qt's own handler).
"""
from __future__ import annotations

import logging
import sys
import traceback

from PySide6.QtWidgets import QApplication, QMessageBox

from fluorogui import __version__
from fluorogui.logs import log_file_path

_active = False  # an exception while the dialog is up is only logged


def crash_report(window, exc_type, exc, tb) -> dict:
    """Log the exception, autosave the session; returns what the dialog shows."""
    logging.getLogger("fluorogui").error("Uncaught exception in the desktop app", exc_info=(exc_type, exc, tb))
    autosave = None
    try:
        if window is not None and window.autosave():
            autosave = window.recovery_path()
    except Exception:  # noqa: BLE001 - the report must still be shown
        logging.getLogger("fluorogui").exception("Autosave after a crash failed")
    details = "".join(traceback.format_exception(exc_type, exc, tb))
    summary = f"{exc_type.__name__}: {exc}" if str(exc) else exc_type.__name__
    return {"summary": summary, "autosave": autosave, "log": log_file_path(),
            "details": f"fluorogui {__version__}\n{details}"}


def crash_dialog(window, report: dict) -> QMessageBox:
    box = QMessageBox(window)
    box.setObjectName("crashDialog")
    box.setIcon(QMessageBox.Icon.Critical)
    box.setWindowTitle("fluorogui: internal error")
    box.setText(f"Something went wrong inside fluorogui:\n{report['summary']}")
    saved = (f"Your unsaved work was autosaved to {report['autosave']}; it is offered when fluorogui next starts."
             if report["autosave"] else "There were no unsaved changes to autosave.")
    box.setInformativeText(f"{saved}\n\nThe log file with the details: {report['log']}\n\n"
                           "You can keep working, but saving under a new name (Save As) is safest.")
    box.setDetailedText(report["details"])
    copy = box.addButton("Copy details", QMessageBox.ButtonRole.ActionRole)
    copy.clicked.disconnect()  # keep the dialog open after copying
    copy.clicked.connect(lambda: QApplication.clipboard().setText(report["details"]))
    box.addButton(QMessageBox.StandardButton.Close)
    box.copy_button = copy
    return box


def install_crash_handler(window) -> None:
    """Make ``sys.excepthook`` report uncaught exceptions in ``window``'s app."""
    previous = sys.excepthook

    def hook(exc_type, exc, tb):
        global _active
        if issubclass(exc_type, KeyboardInterrupt):
            previous(exc_type, exc, tb)
            return
        report = crash_report(window, exc_type, exc, tb)
        if _active or QApplication.instance() is None:
            sys.stderr.write(report["details"])
            return
        _active = True
        try:
            crash_dialog(window, report).exec()
        finally:
            _active = False

    sys.excepthook = hook
