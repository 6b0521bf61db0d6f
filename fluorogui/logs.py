"""The log file: one rotating file in the user's data folder that keeps internal errors'
tracebacks and third-party warnings (VTK, libpng, tifffile) off the terminal.

The command line and the app call ``setup_logging()`` once at start; ``log_file_path()``
is what the About dialog and error messages show. Qt-free.
"""
from __future__ import annotations

import logging
import logging.handlers
import os
import warnings
from pathlib import Path

LOG_NAME = "fluorogui.log"
_MAX_BYTES = 2_000_000
_BACKUPS = 3


def data_dir() -> Path:
    """The user's fluorogui data folder (``FLUOROGUI_DATA_DIR`` overrides)."""
    override = os.environ.get("FLUOROGUI_DATA_DIR")
    if override:
        return Path(override)
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "fluorogui"


def log_file_path() -> Path:
    """Where the log file is (or will be, once something is logged)."""
    return data_dir() / "logs" / LOG_NAME


def setup_logging(verbose: bool = False) -> Path | None:
    """Send the ``fluorogui`` logger and Python warnings to the rotating log file.

    With ``verbose`` they also go to stderr. Returns the log path, or None when the data
    folder cannot be written (then logging stays on stderr only, at warning level).
    """
    root = logging.getLogger()
    for handler in list(root.handlers):
        if getattr(handler, "_fluorogui", False):
            root.removeHandler(handler)
            handler.close()
    path = log_file_path()
    handlers: list[logging.Handler] = []
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        file_handler = logging.handlers.RotatingFileHandler(
            path, maxBytes=_MAX_BYTES, backupCount=_BACKUPS, encoding="utf-8", delay=True)
        file_handler.setFormatter(logging.Formatter(
            "%(asctime)s %(process)d %(levelname)s %(name)s: %(message)s"))
        handlers.append(file_handler)
    except OSError:
        path = None
    if verbose or path is None:
        handlers.append(logging.StreamHandler())
    for handler in handlers:
        handler._fluorogui = True
        root.addHandler(handler)
    root.setLevel(logging.INFO)
    logging.captureWarnings(True)
    if not verbose:
        warnings.simplefilter("default")
    return path


def log_exception(message: str) -> Path | None:
    """Log the exception being handled with its traceback; return the log path if any."""
    logging.getLogger("fluorogui").exception(message)
    path = log_file_path()
    return path if path.exists() else None
