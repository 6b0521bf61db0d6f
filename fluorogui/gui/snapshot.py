"""Open the real main window, show a session and save a screenshot of the screen it is on.

Used for quick pictures, the Xvfb pixel test and start-up timing (the docs' screenshots
are made by ``docs/screenshots/make_screenshots.py``)::

    python -m fluorogui.gui.snapshot OUT.png [--project FILE | --import-folder DIR]
        [--size 1280x800] [--frame N] [--find] [--match | --match-both] [--track-both]
        [--show-frame N] [--component NAME] [--theme light|dark] [--dock matcher|pose|session|kinematics] [--edges]
        [--contact]

Frames are frame numbers. The steps run in this order: find, match, track (from
``--frame`` through the following frames), then ``--show-frame`` picks the frame on
screen for the picture. The screen grab (not ``QWidget.grab``) is used so OpenGL content
is included. Prints one JSON line: the seconds to a usable window, to the first frame on
screen and per task, the frame states after the work and the panel regions.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    t0 = time.perf_counter()
    parser = argparse.ArgumentParser(prog="fluorogui.gui.snapshot")
    parser.add_argument("out", type=Path)
    parser.add_argument("--project", type=Path)
    parser.add_argument("--import-folder", type=Path)
    parser.add_argument("--size", default="1280x800")
    parser.add_argument("--frame", type=int, help="frame number to start on (default: the first)")
    parser.add_argument("--find", action="store_true", help="find the implants automatically first")
    parser.add_argument("--match", action="store_true", help="match the active component")
    parser.add_argument("--match-both", "--match-all", dest="match_both", action="store_true",
                        help="match every component (Match both)")
    parser.add_argument("--track-both", action="store_true", help="Track both through the following frames")
    parser.add_argument("--show-frame", type=int, help="frame number on screen for the picture")
    parser.add_argument("--component")
    parser.add_argument("--theme", default="system")
    parser.add_argument("--dock", choices=["matcher", "pose", "session", "kinematics"],
                        help="the tab raised on the right")
    parser.add_argument("--edges", action="store_true", help="show the Canny edges (View > Show edges)")
    parser.add_argument("--contact", action="store_true",
                        help="the Kinematics dock's contact plot, and the condyle points in the 3D scene")
    parser.add_argument("--settings", type=Path, help="QSettings ini file (default: a temporary one)")
    args = parser.parse_args(argv)

    from PySide6.QtCore import QEventLoop, QSettings, QTimer
    from PySide6.QtWidgets import QApplication

    from fluorogui.gui import theme
    from fluorogui.gui.app import make_application
    from fluorogui.gui.main_window import MainWindow

    app = make_application()
    theme.apply_theme(app, args.theme)
    ini = args.settings or Path(args.out).with_suffix(".ini")
    settings = QSettings(str(ini), QSettings.Format.IniFormat)
    settings.clear()
    w, h = (int(x) for x in args.size.split("x"))
    window = MainWindow(settings=settings)
    window.resize(w, h)
    # the window centres itself at its own first size; at the requested size it must stay on
    # the screen, or the grab shows black where it runs off the edge
    area = window.screen().availableGeometry()
    window.move(area.x() + max(0, (area.width() - w) // 2), area.y() + max(0, (area.height() - h) // 2))
    window.show()
    app.processEvents()
    t_window = time.perf_counter() - t0

    def wait(ms: int) -> None:
        loop = QEventLoop()
        QTimer.singleShot(ms, loop.quit)
        loop.exec()

    if args.project:
        ok = window.open_project(args.project, ask=False)
    elif args.import_folder:
        from fluorogui.io.importer import detect_biplane_folder, import_session

        found = detect_biplane_folder(args.import_folder)
        if not found:
            print(f"{args.import_folder}: not a biplane data folder", file=sys.stderr)
            return 2
        window.controller.set_project(import_session(**found), None)
        ok = True
    else:
        ok = window.open_demo(ask=False)
    if not ok:
        print(f"could not open the session: {window.last_error}", file=sys.stderr)
        return 2
    if args.component:
        window.controller.set_component(args.component)
    if args.frame is not None:
        window.controller.set_frame(args.frame)
    window.fit_images()
    app.processEvents()
    t_first = time.perf_counter() - t0
    timings = {"window_s": round(t_window, 3), "first_frame_s": round(t_first, 3)}

    def run(start) -> float:
        loop = QEventLoop()
        window.runner.finished.connect(loop.quit)
        window.runner.failed.connect(loop.quit)
        window.runner.cancelled.connect(loop.quit)
        t = time.perf_counter()
        if start():
            loop.exec()
        window.runner.finished.disconnect(loop.quit)
        window.runner.failed.disconnect(loop.quit)
        window.runner.cancelled.disconnect(loop.quit)
        return round(time.perf_counter() - t, 3)

    if args.find:
        timings["find_s"] = run(window.find_implants)
    if args.match_both:
        timings["match_both_s"] = run(window.match_both)
    elif args.match:
        timings[f"match_{window.controller.component}_s"] = run(window.run_match)
    if args.track_both:
        timings["track_both_s"] = run(window.track_both)
    if args.show_frame is not None:
        window.controller.set_frame(args.show_frame)
    if args.dock:
        window.docks[args.dock].raise_()
    if args.contact:
        kinematics = window.presenters.kinematics
        window.docks["kinematics"].raise_()
        window.knee_panel.plot.setCurrentIndex(window.knee_panel.plot.findData("contact"))
        kinematics.toggle_contact_points(True)
        t = time.perf_counter()
        while kinematics.contact_stale or kinematics.contact_runner.is_running():
            if time.perf_counter() - t > 120:
                break
            wait(50)
        timings["contact_s"] = round(time.perf_counter() - t, 3)
    if args.edges:
        window.display.toggle_edges(True)
    session = window.controller.session
    timings["frame_states"] = {str(f): s.name for f, s in zip(session.frames, session.frame_states())}
    timings["summary"] = window.matcher.summary.text()
    timings["error"] = window.last_error
    wait(600)
    window.fit_images()
    wait(300)
    # the Kinematics dock redraws 0.4 s after the poses change, and under Xvfb its figure was
    # painted up to 1.3 s after that while the image panels and the 3D scene repainted: wait
    # for its timers and the paint, or the grab shows the curves of before a match beside the
    # values after it
    timers = (window.presenters.kinematics.refresh_timer, window.knee_panel._redraw_timer)
    t = time.perf_counter()
    while any(timer.isActive() for timer in timers) and time.perf_counter() - t < 10:
        wait(50)
    wait(1500)
    geometry = window.frameGeometry()
    shot = window.screen().grabWindow(0, geometry.x(), geometry.y(), geometry.width(), geometry.height())
    if shot.isNull() or shot.width() < 10:
        shot = window.grab()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    shot.save(str(args.out))
    timings["screenshot"] = str(args.out)

    def region(widget):
        top_left = widget.mapTo(window, widget.rect().topLeft())
        offset = window.geometry().topLeft() - geometry.topLeft()  # window frame, if any
        return [top_left.x() + offset.x(), top_left.y() + offset.y(), widget.width(), widget.height()]

    timings["regions"] = {f"view{i + 1}": region(p) for i, p in enumerate(window.panels)}
    if window.scene_widget is not None and window.scene_widget.isVisible():
        timings["regions"]["scene"] = region(window.scene_widget)
        timings["scene_interactive"] = window.scene_widget.interactive
    print(json.dumps(timings))
    session.history.set_clean()
    window.close()
    QApplication.processEvents()
    return 0


if __name__ == "__main__":
    sys.exit(main())
