"""The app's folders and its log file: one rotating file that keeps internal errors'
tracebacks and third-party warnings (VTK, libpng, tifffile) off the terminal.

The folders are where each operating system expects an application's files
(``platformdirs``; no vendor folder; local rather than roaming on Windows):

* data (the crash-recovery autosave, the demo): ``~/.local/share/fluorogui`` on Linux,
  ``~/Library/Application Support/fluorogui`` on macOS, ``%LOCALAPPDATA%\\fluorogui`` on Windows;
* log: ``~/.local/state/fluorogui/log``, ``~/Library/Logs/fluorogui``,
  ``%LOCALAPPDATA%\\fluorogui\\Logs``;
* cache: ``~/.cache/fluorogui``, ``~/Library/Caches/fluorogui``, ``%LOCALAPPDATA%\\fluorogui\\Cache``

(on Linux the ``XDG_DATA_HOME`` / ``XDG_STATE_HOME`` / ``XDG_CACHE_HOME`` variables move them).
``FLUOROGUI_DATA_DIR`` puts all three in one folder (``logs/`` and ``cache/`` inside it):
tests, the build check and portable installs use it.

The command line and the app call ``setup_logging()`` once at start; ``log_file_path()``
is what the About dialog and error messages show. Qt-free.
"""
from __future__ import annotations

import logging
import logging.handlers
import os
import warnings
from pathlib import Path

import platformdirs

APP_NAME = "fluorogui"
DATA_DIR_ENV = "FLUOROGUI_DATA_DIR"
LOG_NAME = "fluorogui.log"
_MAX_BYTES = 2_000_000
_BACKUPS = 3


def _override() -> Path | None:
    value = os.environ.get(DATA_DIR_ENV)
    return Path(value) if value else None


def data_dir() -> Path:
    """The user's fluorogui data folder: the crash-recovery autosave and the demo."""
    override = _override()
    return override if override is not None else Path(platformdirs.user_data_dir(APP_NAME, appauthor=False))


def log_dir() -> Path:
    """The folder of the log file."""
    override = _override()
    return override / "logs" if override is not None else Path(platformdirs.user_log_dir(APP_NAME, appauthor=False))


def cache_dir() -> Path:
    """The folder for what can be made again (generated files)."""
    override = _override()
    return override / "cache" if override is not None else Path(platformdirs.user_cache_dir(APP_NAME, appauthor=False))


def log_file_path() -> Path:
    """Where the log file is (or will be, once something is logged)."""
    return log_dir() / LOG_NAME


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


FATAL_LOG_NAME = "fatal.log"
_fatal_file = None  # kept open: faulthandler writes to it when the process dies


def record_fatal_errors() -> Path | None:
    """Have a fatal error (an abort or a segmentation fault in a C extension, which no
    Python handler sees) write every thread's Python stack to ``fatal.log`` beside the log
    file; returns its path, or None when it cannot be written."""
    import faulthandler

    global _fatal_file
    path = log_dir() / FATAL_LOG_NAME
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if _fatal_file is None:
            _fatal_file = open(path, "a", encoding="utf-8")  # open for the process's life
        faulthandler.enable(file=_fatal_file, all_threads=True)
    except OSError:
        return None
    return path


def log_exception(message: str) -> Path | None:
    """Log the exception being handled with its traceback; return the log path if any."""
    logging.getLogger("fluorogui").exception(message)
    path = log_file_path()
    return path if path.exists() else None
