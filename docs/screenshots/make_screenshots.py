"""Make the user guides' screenshots from the real desktop app (run under Xvfb).

Opens the real main window (as ``fluorogui.gui.snapshot`` does), drives it through the
tasks the guides describe, and saves one PNG per step into this folder::

    xvfb-run -a -s "-screen 0 1600x1000x24" python docs/screenshots/make_screenshots.py \
        [--data PATH/TO/shared/data] [--only NAME ...]

Without ``--data`` only the demo's pictures are made (the demo is generated; nothing
else is needed). With ``--data`` (a folder holding ``biplane-tka/`` and
``single-plane-tka/``) also the real biplane and single-plane pictures. The PNGs are
committed; the docs build does not run this (it needs a display and takes minutes).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SIZE = (1440, 900)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, help="folder with biplane-tka/ and single-plane-tka/")
    parser.add_argument("--out", type=Path, default=HERE)
    parser.add_argument("--only", nargs="+", metavar="NAME", help="make only these pictures (file stems)")
    args = parser.parse_args(argv)

    from PySide6.QtCore import QEventLoop, QSettings, QTimer

    from fluorogui.gui import theme
    from fluorogui.gui.app import make_application
    from fluorogui.gui.main_window import MainWindow

    app = make_application()
    theme.apply_theme(app, "light")
    scratch = Path(tempfile.mkdtemp(prefix="fluorogui-shots-"))
    settings = QSettings(str(scratch / "shots.ini"), QSettings.Format.IniFormat)
    settings.clear()
    made = []

    def wait(ms: int) -> None:
        loop = QEventLoop()
        QTimer.singleShot(ms, loop.quit)
        loop.exec()

    def wanted(name: str) -> bool:
        return not args.only or name in args.only

    def new_window() -> MainWindow:
        window = MainWindow(settings=settings)
        window.resize(*SIZE)
        window.show()
        app.processEvents()
        return window

    def run_task(window: MainWindow, start) -> None:
        loop = QEventLoop()
        runner = window.runner
        for signal in (runner.finished, runner.failed, runner.cancelled):
            signal.connect(loop.quit)
        if start():
            loop.exec()
        for signal in (runner.finished, runner.failed, runner.cancelled):
            signal.disconnect(loop.quit)
        wait(300)

    def shoot(widget, name: str) -> None:
        wait(500)
        if hasattr(widget, "fit_images"):
            widget.fit_images()
            wait(300)
        geometry = widget.frameGeometry()
        shot = widget.screen().grabWindow(0, geometry.x(), geometry.y(), geometry.width(), geometry.height())
        if shot.isNull() or shot.width() < 10:
            shot = widget.grab()
        path = args.out / f"{name}.png"
        shot.save(str(path))
        made.append(path)
        print(f"screenshots: {path.name} ({shot.width()}x{shot.height()})", file=sys.stderr, flush=True)

    # -- the demo: find, match, review, track, kinematics, export ------------------------------
    demo_names = ("app-demo", "app-matched", "app-tracked", "app-kinematics", "dialog-export", "dialog-import",
                  "dialog-calibration")
    if any(wanted(n) for n in demo_names):
        window = new_window()
        if not window.open_demo(ask=False):
            print(f"screenshots: could not open the demo: {window.last_error}", file=sys.stderr)
            return 2
        window.fit_images()
        if wanted("app-demo"):
            shoot(window, "app-demo")
        run_task(window, window.find_implants)
        run_task(window, window.match_both)
        window.matcher_dock.raise_()
        if wanted("app-matched"):
            shoot(window, "app-matched")
        run_task(window, window.track_both)
        session = window.controller.session
        window.controller.set_frame(session.frames[-1])
        window.session_dock.raise_()
        if wanted("app-tracked"):
            shoot(window, "app-tracked")
        window.knee_dock.raise_()
        if wanted("app-kinematics"):
            shoot(window, "app-kinematics")
        if wanted("dialog-export"):
            from fluorogui.gui.dialogs.export_dialog import ExportDialog
            from fluorogui.workflow import exports

            dialog = ExportDialog(scratch, "demo", session.n_views, window, fps=exports.frame_rate(session))
            dialog.show()
            shoot(dialog, "dialog-export")
            dialog.close()
        if wanted("dialog-import"):
            from fluorogui.gui.dialogs.import_dialog import ImportDialog

            dialog = ImportDialog(window)
            dialog.resize(900, 760)
            dialog.show()
            dialog.fill_from_folder(Path(session.path).parent)
            shoot(dialog, "dialog-import")
            dialog.close()
        if wanted("dialog-calibration"):
            from fluorogui.gui.dialogs.calibration_wizard import CalibrationWizard

            wizard = CalibrationWizard(window)
            wizard.resize(900, 700)
            wizard.show()
            shoot(wizard, "dialog-calibration")
            wizard.close()
        session.history.set_clean()
        window.close()
        app.processEvents()

    # -- the real data -----------------------------------------------------------------------
    if args.data is not None and wanted("real-biplane"):
        from fluorogui.io.importer import import_folder

        window = new_window()
        window.controller.set_project(import_folder(args.data / "biplane-tka"), None)
        window.fit_images()
        run_task(window, window.find_implants)
        run_task(window, window.match_both)
        window.matcher_dock.raise_()
        shoot(window, "real-biplane")
        window.controller.session.history.set_clean()
        window.close()
        app.processEvents()
    if args.data is not None and wanted("single-plane"):
        from fluorogui.io.importer import import_folder
        from fluorogui.workflow import exports

        folder = args.data / "single-plane-tka"
        window = new_window()
        window.controller.set_project(import_folder(folder), None)
        session = window.controller.session
        for name, component in (("fem.jts", "femoral"), ("tib.jts", "tibial")):
            exports.import_poses(session, folder / name, component=component, view=0)
        window.controller.set_frame(session.frames[0])
        window.fit_images()
        window.pose_dock.raise_()
        shoot(window, "single-plane")
        session.history.set_clean()
        window.close()
        app.processEvents()
    print(f"screenshots: made {len(made)} pictures in {time.process_time():.0f} s of CPU", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
