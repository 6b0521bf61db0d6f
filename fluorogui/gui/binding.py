"""Is the Qt binding sound? A check, made once at start, that PySide6 keeps Python's
reference counts.

PySide6 6.12.0 loses a reference to ``None`` on every call of a method that returns
nothing (``setText``, ``setEnabled``, ``processEvents``...) and one to ``True`` on every
signal ``emit``. Before Python 3.12, ``None`` and ``True`` are ordinary objects: after
enough calls their count reaches zero and the interpreter aborts ("Fatal Python error:
none_dealloc: deallocating None"), wherever the last call happened to be; the desktop app
aborted so once while tracking. From Python 3.12 they are immortal and the loss is
harmless. fluorogui's requirements leave that release out; this check catches an
installation that has it anyway, so the app can say so instead of aborting later.
"""
from __future__ import annotations

import sys

#: calls of each kind the check makes; a leaking binding loses one reference per call
CALLS = 40


def reference_leak() -> str | None:
    """None when the binding keeps reference counts, else what it loses, in a sentence
    naming the installed version and what to do."""
    if sys.version_info >= (3, 12):
        return None  # None and True are immortal: nothing to lose
    import PySide6

    lost_none, lost_true = lost_references()
    if lost_none < CALLS // 2 and lost_true < CALLS // 2:
        return None
    return (f"PySide6 {PySide6.__version__} loses a Python reference on every Qt call ({lost_none} to None and "
            f"{lost_true} to True in {CALLS} calls of each kind): on Python {sys.version_info[0]}."
            f"{sys.version_info[1]} a long session then aborts. Install another release, e.g. "
            "pip install \"PySide6-Essentials!=6.12.0\"")


def lost_references() -> tuple[int, int]:
    """References to None and to True lost over ``CALLS`` calls of a Qt method that returns
    nothing and ``CALLS`` signal emits (0, 0 on a sound binding)."""
    from PySide6.QtCore import QObject, QTimer, Signal

    class _Probe(QObject):
        fired = Signal(object)

    probe, timer = _Probe(), QTimer()
    before = sys.getrefcount(None), sys.getrefcount(True)
    for _ in range(CALLS):
        timer.setInterval(5)  # returns nothing
        probe.fired.emit(0)  # returns True
    lost = before[0] - sys.getrefcount(None), before[1] - sys.getrefcount(True)
    del probe, timer
    return lost
