"""Long work off the GUI thread: a QThread that runs a plain callable with progress and cancel.

A task is ``task(reporter) -> result``; it calls ``reporter.report(payload)`` as often as it
likes (only the latest payload is forwarded, at most every ``interval`` seconds, so the
GUI thread is never flooded), ``reporter.emit(payload)`` for items that must all arrive
(a batch's per-frame results), and polls ``reporter.cancelled()``. The runner re-emits, on
the GUI thread: ``progress`` (latest payload), ``item`` (every emitted payload), then
exactly one of ``finished(result)``, ``cancelled()`` or ``failed(message)``; the message
is a plain sentence for the user (``describe_error``), never an exception's class name.
Tasks never touch widgets or VTK; they receive numpy arrays and return plain objects.
"""
from __future__ import annotations

import sys
import threading
import time
import traceback
from typing import Any, Callable

from PySide6.QtCore import QObject, QThread, Signal

from fluorogui.core.cancel import Cancelled, check_cancel
from fluorogui.io.errors import InputError


def describe_error(exc: BaseException) -> str:
    """An exception as a sentence for the user (its message, never its class name).
    Unexpected kinds also go to stderr in full, for a bug report."""
    if isinstance(exc, InputError):
        return str(exc)
    if isinstance(exc, ImportError):
        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
        return (f"A part of fluorogui this needs is not available in this installation ({exc.name or exc}). "
                "Update fluorogui, or work around it (e.g. place the models by hand).")
    text = str(exc).strip()
    if not isinstance(exc, (ValueError, RuntimeError, OSError)):
        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    if not text:
        text = "something went wrong inside fluorogui (the details went to the terminal)"
    text = text[0].upper() + text[1:]
    return text if text.endswith((".", "!", "?")) else text + "."


class Reporter:
    """What a task sees of the runner: throttled progress, guaranteed items, the cancel flag."""

    def __init__(self, thread: "_TaskThread", interval: float) -> None:
        self._thread = thread
        self._interval = interval
        self._last = -1e9
        self._cancel = threading.Event()

    def report(self, payload: Any, force: bool = False) -> bool:
        """Forward ``payload`` unless one went out less than ``interval`` ago. Returns
        whether it was forwarded (so a task can skip building costly payloads)."""
        now = time.perf_counter()
        if not force and now - self._last < self._interval:
            return False
        self._last = now
        self._thread.progress.emit(payload)
        return True

    def due(self) -> bool:
        """Whether a ``report`` now would be forwarded."""
        return time.perf_counter() - self._last >= self._interval

    def emit(self, payload: Any) -> None:
        self._thread.item.emit(payload)

    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def check(self) -> None:
        """Raise ``Cancelled`` once the user cancelled."""
        check_cancel(self.cancelled)


class _TaskThread(QThread):
    progress = Signal(object)
    item = Signal(object)
    done = Signal(object)
    stopped = Signal()
    error = Signal(str)

    def __init__(self, task: Callable, interval: float) -> None:
        super().__init__()
        self.task = task
        self.reporter = Reporter(self, interval)

    def run(self) -> None:  # the worker thread
        try:
            result = self.task(self.reporter)
        except Cancelled:
            self.stopped.emit()
            return
        except Exception as exc:  # noqa: BLE001 (reported to the user, never a crash)
            if self.reporter.cancelled() and not isinstance(exc, InputError):  # its own cancellation
                self.stopped.emit()
                return
            self.error.emit(describe_error(exc))
            return
        if self.reporter.cancelled():
            self.stopped.emit()
        else:
            self.done.emit(result)


class TaskRunner(QObject):
    """Runs one task at a time in a worker thread; signals arrive on the GUI thread."""

    started = Signal(str)
    progress = Signal(object)
    item = Signal(object)
    finished = Signal(object)
    cancelled = Signal()
    failed = Signal(str)
    running_changed = Signal(bool)

    def __init__(self, parent: QObject | None = None, interval: float = 0.05) -> None:
        super().__init__(parent)
        self.interval = interval
        self._thread: _TaskThread | None = None
        self.label = ""
        self.cancel_requested_at: float | None = None
        self.ended_at: float | None = None  # perf_counter when the last task's end arrived

    def is_running(self) -> bool:
        return self._thread is not None

    def start(self, task: Callable, label: str = "") -> bool:
        """Start ``task(reporter)``; False if another task is still running."""
        if self._thread is not None:
            return False
        thread = _TaskThread(task, self.interval)
        thread.progress.connect(self.progress)
        thread.item.connect(self.item)
        thread.done.connect(lambda result: self._end(self.finished, result))
        thread.stopped.connect(lambda: self._end(self.cancelled))
        thread.error.connect(lambda message: self._end(self.failed, message))
        self._thread = thread
        self.label = label
        self.cancel_requested_at = None
        thread.start()
        self.started.emit(label)
        self.running_changed.emit(True)
        return True

    def cancel(self) -> None:
        if self._thread is not None:
            self.cancel_requested_at = time.perf_counter()
            self._thread.reporter._cancel.set()

    def wait(self, ms: int = 10000) -> bool:
        """Block until the task ends (for closing the app and for scripts)."""
        thread = self._thread
        return True if thread is None else thread.wait(ms)

    def _end(self, signal, *args) -> None:
        self.ended_at = time.perf_counter()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.wait()
            thread.deleteLater()
        self.running_changed.emit(False)
        signal.emit(*args)
