"""Developer benchmark of the desktop app: frame switching, event-loop stalls while matching,
cancel latency. Prints a table; run under a display (xvfb-run) with QT_QPA_PLATFORM=xcb.

Usage: xvfb-run -a -s "-screen 0 1920x1080x24" env QT_QPA_PLATFORM=xcb \\
           .venv/bin/python benchmarks/bench_gui.py [--project FILE | --real DIR] [--repeats N]

Start-up time is measured separately by ``python -m fluorogui.gui.snapshot`` (it prints
the seconds to a usable window and to the first frame on screen).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from PySide6.QtCore import QElapsedTimer, QEventLoop, QSettings, QTimer  # noqa: E402

from fluorogui.gui.app import make_application  # noqa: E402
from fluorogui.gui.main_window import MainWindow  # noqa: E402


class StallMeter:
    """Gaps between ticks of a 2 ms timer: how long the event loop was blocked. ``stop(until)``
    returns the largest gap that ended before ``until`` (the task's end reaching the GUI
    thread) and, separately, the one spanning the display of the result."""

    def __init__(self):
        self.timer = QTimer()
        self.timer.setInterval(2)
        self.timer.timeout.connect(self._tick)
        self.clock = QElapsedTimer()
        self.gaps: list[float] = []

    def start(self):
        self.gaps.clear()
        self.clock.start()
        self.timer.start()

    def _tick(self):
        self.gaps.append((time.perf_counter(), self.clock.restart() / 1000.0))

    def stop(self, until: float | None = None) -> tuple[float, float]:
        self.timer.stop()
        until = until if until is not None else float("inf")
        during = [g for t, g in self.gaps if t <= until]
        after = [g for t, g in self.gaps if t > until]
        return (max(during) if during else float("nan"), max(after[:1]) if after else float("nan"))


def QTimerWait(ms: int) -> None:  # noqa: N802
    loop = QEventLoop()
    QTimer.singleShot(ms, loop.quit)
    loop.exec()


def wait_for(signal_list, start) -> float:
    loop = QEventLoop()
    for s in signal_list:
        s.connect(loop.quit)
    t = time.perf_counter()
    if start():
        loop.exec()
    for s in signal_list:
        s.disconnect(loop.quit)
    return time.perf_counter() - t


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--project", type=Path)
    parser.add_argument("--real", type=Path, help="a biplane data folder to import (e.g. ../shared/data/biplane-tka)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--no-3d", action="store_true", help="without the 3D panel (to separate its cost)")
    args = parser.parse_args()

    app = make_application()
    settings = QSettings(str(Path(tempfile.mkdtemp()) / "bench.ini"), QSettings.Format.IniFormat)
    window = MainWindow(settings=settings, with_3d=not args.no_3d)
    window.resize(1920, 1080)
    window.show()
    app.processEvents()
    if args.real:
        from fluorogui.io.importer import detect_biplane_folder, import_session

        window.controller.set_project(import_session(**detect_biplane_folder(args.real)), None)
    elif args.project:
        window.open_project(args.project, ask=False)
    else:
        window.open_demo(ask=False)
    c = window.controller
    app.processEvents()
    rows = []

    # frame switching: first visit (read from disk) and revisit (cached), both views, 3D textures
    n = min(len(c.frames), 12)
    cold, warm = [], []
    for times in (cold, warm):
        for i in list(range(1, n)) + [0]:
            t = time.perf_counter()
            c.set_frame(c.frames[i])
            app.processEvents()
            times.append(time.perf_counter() - t)
    shape = c.session.image(c.frame, 0).shape
    rows.append((f"frame switch, first visit ({shape[1]}x{shape[0]} pair)", statistics.median(cold), max(cold)))
    rows.append(("frame switch, cached", statistics.median(warm), max(warm)))

    # matching: event-loop stall and duration
    if args.real:
        wait_for([window.runner.finished, window.runner.failed], window.find_implants)
    meter = StallMeter()
    stalls, shows, durations = [], [], []
    for _ in range(args.repeats):
        record = c.session.pose_record(c.component, c.frame)
        if c.undo_stack.canUndo() and record is not None and record.match is not None:
            c.undo_stack.undo()  # back to the unmatched start
        meter.start()
        durations.append(wait_for([window.runner.finished, window.runner.failed], window.run_match))
        QTimerWait(300)
        during, show = meter.stop(window.runner.ended_at)
        stalls.append(during)
        shows.append(show)
    rows.append(("match (fast, auto outlines), wall time", statistics.median(durations), max(durations)))
    rows.append(("worst event-loop stall while a match runs", statistics.median(stalls), max(stalls)))
    rows.append(("showing the result (outlines, overlays, 3D) at the end", statistics.median(shows), max(shows)))

    # cancel latency: paper method (long), cancel after the first live update
    latencies, cancel_stalls = [], []
    window.matcher.method.setCurrentIndex(1)
    for _ in range(args.repeats):
        fired = []

        def cancel_once(_payload, fired=fired):
            if not fired:
                fired.append(1)
                window.runner.cancel()

        window.runner.progress.connect(cancel_once)
        meter.start()
        wait_for([window.runner.cancelled, window.runner.finished, window.runner.failed], window.run_match)
        QTimerWait(300)
        cancel_stalls.append(meter.stop(window.runner.ended_at)[0])
        window.runner.progress.disconnect(cancel_once)
        if window.tasks.last_cancel_latency is not None:
            latencies.append(window.tasks.last_cancel_latency)
    window.matcher.method.setCurrentIndex(0)
    if latencies:
        rows.append(("cancel latency (request to 'cancelled' on the GUI thread)", statistics.median(latencies),
                     max(latencies)))
    rows.append(("worst event-loop stall while a paper-method match runs", statistics.median(cancel_stalls),
                 max(cancel_stalls)))

    print(f"{'measure':<62} {'median s':>9} {'max s':>9}")
    for name, med, worst in rows:
        print(f"{name:<62} {med:9.4f} {worst:9.4f}")
    c.session.history.set_clean()
    window.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
