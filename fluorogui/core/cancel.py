"""What every long job shares: the one ``Cancelled`` exception and the cancel check.

A long job (a match, a search, tracking, a calibration fit) takes ``cancel``, a
callable returning True once the caller wants it to stop, and raises ``Cancelled`` when
it sees that; nothing is returned to mean "cancelled". The GUI's worker, the command
line and scripts all catch this one type.

A job with a time limit passes on ``with_deadline(cancel, deadline)``: the same checks
then raise ``OutOfTime`` once the deadline has passed, and the job that set it keeps what
it had found (``workflow.framematch``: a component's match in a frame).
"""
from __future__ import annotations

import time
from typing import Callable

CancelFlag = Callable[[], bool]


class Cancelled(Exception):
    """The caller's cancel flag was set: the job stopped and its partial result is dropped."""


def check_cancel(cancel: CancelFlag | None) -> None:
    """Raise ``Cancelled`` when ``cancel`` is given and returns True."""
    if cancel is not None and cancel():
        raise Cancelled


class OutOfTime(Exception):
    """A time limit set with ``with_deadline`` passed: the work stops at its next check, and
    the caller that set the limit keeps what it had (unlike ``Cancelled``)."""


def with_deadline(cancel: CancelFlag | None, deadline: float | None) -> CancelFlag | None:
    """``cancel`` that also raises ``OutOfTime`` when checked after ``deadline`` (a
    ``time.perf_counter()`` value); ``cancel`` itself when ``deadline`` is None. The
    caller's own cancel comes first."""
    if deadline is None:
        return cancel

    def check() -> bool:
        if cancel is not None and cancel():
            return True
        if time.perf_counter() > deadline:
            raise OutOfTime
        return False

    return check
