"""Time left of a long task from a moving average of its recent steps (Qt-free).

The first frame of a track or the first percent of a search says little about the rest:
an exponential moving average of the time per unit of work follows the task as it goes.
"""
from __future__ import annotations

import time

SMOOTHING = 0.4  # weight of the newest step in the moving average


class Eta:
    """Seconds left from progress updates (``done`` of ``total`` units, any scale)."""

    def __init__(self, total: float = 1.0, clock=time.perf_counter, smoothing: float = SMOOTHING):
        self.total = float(total)
        self.clock = clock
        self.smoothing = float(smoothing)
        self.reset(total)

    def reset(self, total: float | None = None) -> None:
        if total is not None:
            self.total = float(total)
        self._last = (0.0, self.clock())
        self.rate: float | None = None  # seconds per unit, moving average

    def update(self, done: float, now: float | None = None) -> float | None:
        """Record progress; returns the seconds left (None until a step has been timed)."""
        now = self.clock() if now is None else float(now)
        last_done, last_time = self._last
        if done > last_done:
            step_rate = (now - last_time) / (done - last_done)
            self.rate = step_rate if self.rate is None else (
                self.smoothing * step_rate + (1.0 - self.smoothing) * self.rate)
            self._last = (float(done), now)
        return self.left(done)

    def left(self, done: float) -> float | None:
        if self.rate is None:
            return None
        return max(self.total - float(done), 0.0) * self.rate


def describe(seconds: float | None) -> str:
    """'about 40 s left', 'about 3 min left', '' when unknown."""
    if seconds is None:
        return ""
    if seconds < 1:
        return "under a second left"
    if seconds < 90:
        return f"about {seconds:.0f} s left"
    return f"about {seconds / 60:.0f} min left"
