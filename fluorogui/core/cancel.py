"""What every long job shares: the one ``Cancelled`` exception and the cancel check.

A long job (a match, a search, tracking, a calibration fit) takes ``cancel``, a
callable returning True once the caller wants it to stop, and raises ``Cancelled`` when
it sees that; nothing is returned to mean "cancelled". The GUI's worker, the command
line and scripts all catch this one type.
"""
from __future__ import annotations

from typing import Callable

CancelFlag = Callable[[], bool]


class Cancelled(Exception):
    """The caller's cancel flag was set: the job stopped and its partial result is dropped."""


def check_cancel(cancel: CancelFlag | None) -> None:
    """Raise ``Cancelled`` when ``cancel`` is given and returns True."""
    if cancel is not None and cancel():
        raise Cancelled
