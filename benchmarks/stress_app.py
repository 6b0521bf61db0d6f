"""Stress run of the desktop app: *Track both* again and again on the real biplane data, with
the Kinematics dock on screen redrawing as frames arrive (issue 44, item 1).

The app once aborted after a long session ("Fatal Python error: none_dealloc: deallocating
None"). The cause was the Qt binding: PySide6 6.12.0 loses a reference to ``None`` on every
call of a method that returns nothing, and one to ``True`` on every signal ``emit``; on
Python 3.11 (where ``None`` and ``True`` are not immortal) the count reaches zero after
enough calls and the interpreter aborts wherever that happens to be. Waiting for the abort
takes long and depends on how many references the rest of the program holds, so this run
also prints the reference counts of ``None``, ``True`` and ``False`` after every track: on
a sound binding they stay put from track to track; on a leaking one they fall by
thousands per track, and the track at which ``None`` reaches zero can be read off.

Usage (a real window needs a display: xvfb-run gives one)::

    xvfb-run -a -s "-screen 0 1920x1080x24" .venv/bin/python benchmarks/stress_app.py --tracks 50
    ... --frames 0:60 --no-3d --json stress.jsonl

``faulthandler`` is on: an abort prints every thread's Python stack on stderr. Exit status 0
when every track finished, 1 otherwise. Needs ../shared/data/biplane-tka.
"""
from __future__ import annotations

import argparse
import faulthandler
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
DATA = ROOT.parent / "shared" / "data" / "biplane-tka"


def reference_counts() -> dict:
    return {"none": sys.getrefcount(None), "true": sys.getrefcount(True), "false": sys.getrefcount(False)}


def _wait_for(runner, timeout_s: float) -> bool:
    """Run the event loop, as the app does, until the runner's task has ended (False on
    timeout). (A loop of ``processEvents`` calls would be a Python call into Qt every few
    milliseconds, which the app does not make.)"""
    from PySide6.QtCore import QEventLoop, QTimer

    if not runner.is_running():
        return True
    loop = QEventLoop()
    runner.running_changed.connect(loop.quit)
    timer = QTimer()
    timer.setSingleShot(True)
    timer.timeout.connect(loop.quit)
    timer.start(int(timeout_s * 1000))
    loop.exec()
    runner.running_changed.disconnect(loop.quit)
    return not runner.is_running()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tracks", type=int, default=50, help="Track both runs (default 50)")
    parser.add_argument("--frames", default=None, metavar="A:B",
                        help="only the frames from A to B (both included; default all)")
    parser.add_argument("--no-3d", action="store_true", help="leave out the 3D panel")
    parser.add_argument("--json", metavar="OUT", help="one JSON line per track")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds a track may take")
    args = parser.parse_args(argv)
    if not DATA.is_dir():
        print(f"stress_app: {DATA} not found", file=sys.stderr)
        return 2
    faulthandler.enable(all_threads=True)
    os.environ.setdefault("FLUOROGUI_DATA_DIR", tempfile.mkdtemp(prefix="fluorogui-stress-"))

    from PySide6.QtCore import QSettings

    from fluorogui.gui.app import make_application
    from fluorogui.gui.binding import reference_leak
    from fluorogui.gui.main_window import MainWindow
    from fluorogui.io.importer import import_folder

    app = make_application()
    leak = reference_leak()
    print(f"Qt binding: {leak or 'keeps reference counts'}", flush=True)
    ini = Path(os.environ["FLUOROGUI_DATA_DIR"]) / "settings.ini"
    window = MainWindow(settings=QSettings(str(ini), QSettings.Format.IniFormat), with_3d=not args.no_3d)
    window.resize(1600, 1000)
    window.show()
    project = import_folder(DATA)
    if args.frames:
        a, b = (int(v) for v in args.frames.split(":"))
        project.frames = [f for f in project.frames if a <= f <= b]
    window.controller.set_project(project, None)
    window.knee_dock.show()
    window.knee_dock.raise_()  # the Kinematics dock redraws as tracked frames arrive
    app.processEvents()
    first = window.controller.frames[0]
    window.controller.set_frame(first)
    window.tasks.find_implants()
    _wait_for(window.runner, args.timeout)
    out = open(args.json, "w") if args.json else None
    finished = 0
    start_counts = reference_counts()
    print(f"{'track':>5} {'seconds':>8} {'matched':>7} {'review':>6} {'failed':>6} "
          f"{'None refs':>10} {'True refs':>10} {'False refs':>10}", flush=True)
    for k in range(1, args.tracks + 1):
        window.controller.set_frame(first)
        t0 = time.perf_counter()
        if not window.tasks.track_both():
            print(f"track {k}: could not start", file=sys.stderr)
            break
        if not _wait_for(window.runner, args.timeout):
            print(f"track {k}: did not finish in {args.timeout:.0f} s", file=sys.stderr)
            break
        seconds = time.perf_counter() - t0
        summary = window.tasks.last_track
        counts = reference_counts()
        row = {"track": k, "seconds": round(seconds, 2), "matched": len(summary.matched),
               "needs_review": len(summary.review), "failed": len(summary.failed), **counts}
        print(f"{k:5d} {seconds:8.1f} {row['matched']:7d} {row['needs_review']:6d} {row['failed']:6d} "
              f"{counts['none']:10d} {counts['true']:10d} {counts['false']:10d}", flush=True)
        if out is not None:
            out.write(json.dumps(row) + "\n")
            out.flush()
        finished += 1
    end_counts = reference_counts()
    drift = {name: end_counts[name] - start_counts[name] for name in end_counts}
    print(f"{finished} of {args.tracks} tracks finished; reference counts from the first to the last: {drift}",
          flush=True)
    window.controller.session.history.set_clean()
    window.close()
    return 0 if finished == args.tracks else 1


if __name__ == "__main__":
    sys.exit(main())
