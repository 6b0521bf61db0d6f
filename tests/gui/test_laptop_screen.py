"""The app on a laptop screen: the first window fits 1280×720 and 1366×768 (checked on Qt
screens of those sizes in a child process), the Kinematics curves keep a readable size
(they scroll, or open in a window of their own), a long review reason is one line with
the details on demand, and exports start in the project's folder."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import Qt  # noqa: E402
from PySide6.QtGui import QFontMetrics  # noqa: E402
from PySide6.QtWidgets import QDialog  # noqa: E402

from fluorogui.core.records import PoseRecord  # noqa: E402
from fluorogui.core.status import Status  # noqa: E402
from fluorogui.gui.dialogs.export_dialog import ExportDialog  # noqa: E402
from fluorogui.gui.panels.knee_panel import PLOT_MIN_SIZE  # noqa: E402
from fluorogui.gui.panels.matcher_panel import MatcherPanel  # noqa: E402
from fluorogui.workflow import exports  # noqa: E402

FIRST_START = """
import json, sys
from PySide6.QtCore import QSettings
from PySide6.QtWidgets import QApplication
from fluorogui.gui.main_window import MainWindow
app = QApplication([])
window = MainWindow(settings=QSettings(sys.argv[1], QSettings.Format.IniFormat))
window.show()
app.processEvents()
area = window.screen().availableGeometry()
frame = window.frameGeometry()
status = window.statusBar()
bottom = status.mapToGlobal(status.rect().bottomLeft()).y()
first = [frame.x(), frame.y(), frame.width(), frame.height()]
window.resize(3000, 2000)  # as if restored from a larger monitor
window.fit_to_screen()
print(json.dumps({"area": [area.width(), area.height()], "first": first, "status_bottom": bottom,
                  "shrunk": [window.width(), window.height()]}))
window.close()
"""

LAST_SIZE = """
import json, sys
from PySide6.QtCore import QSettings
from PySide6.QtWidgets import QApplication, QToolBar, QToolButton
from fluorogui.gui.main_window import MainWindow
app = QApplication([])
window = MainWindow(settings=QSettings(sys.argv[1], QSettings.Format.IniFormat), with_3d=False)
window.show()
if sys.argv[2] == "save":
    window.resize(1800, 1000)  # a wide monitor
    app.processEvents()
    window.close()  # saves the geometry
    sys.exit(0)
app.processEvents()
area = window.screen().availableGeometry()
frame = window.frameGeometry()
toolbar = window.findChild(QToolBar, "mainToolbar")
more = toolbar.findChild(QToolButton, "qt_toolbar_ext_button")  # the toolbar's overflow button
print(json.dumps({"area": [area.x(), area.y(), area.width(), area.height()],
                  "frame": [frame.x(), frame.y(), frame.width(), frame.height()],
                  "overflow": more is not None and more.isVisible()}))
window.close()
"""

LONG_REASON = ("outline distance 2.31 mm in view 1 (limit 0.90 mm, typical 0.30 mm); only 41 % of the model "
               "outline lies on image edges in view 1; moved 6.2 mm / 4.1° from the predicted pose")


@pytest.mark.parametrize("width, height", [(1280, 720), (1366, 768), (1920, 1080)])
@pytest.mark.slow
def test_the_first_window_fits_the_screen(width, height, tmp_path):
    screens = tmp_path / "screens.json"
    screens.write_text(json.dumps({"screens": [{"name": "s", "x": 0, "y": 0, "width": width, "height": height,
                                                "logicalDpi": 96, "logicalBaseDpi": 96, "dpr": 1}]}))
    env = dict(os.environ, QT_QPA_PLATFORM=f"offscreen:configfile={screens}",
               FLUOROGUI_DATA_DIR=str(tmp_path / "appdata"))
    run = subprocess.run([sys.executable, "-c", FIRST_START, str(tmp_path / "settings.ini")], env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout.strip().splitlines()[-1])
    assert result["area"] == [width, height]
    x, y, w, h = result["first"]
    assert x >= 0 and y >= 0 and x + w <= width and y + h <= height, result
    assert result["status_bottom"] < height  # the status bar (and the timeline above it) on screen
    assert w >= min(1280, width) - 16 and h >= min(800, height) - 40  # and uses the room there is
    assert result["shrunk"][0] <= width and result["shrunk"][1] <= height


def _screen_env(tmp_path, width, height):
    screens = tmp_path / f"screens-{width}.json"
    screens.write_text(json.dumps({"screens": [{"name": "s", "x": 0, "y": 0, "width": width, "height": height,
                                                "logicalDpi": 96, "logicalBaseDpi": 96, "dpr": 1}]}))
    return dict(os.environ, QT_QPA_PLATFORM=f"offscreen:configfile={screens}",
                FLUOROGUI_DATA_DIR=str(tmp_path / "appdata"))


@pytest.mark.slow
def test_a_window_saved_on_a_wide_monitor_reopens_filling_a_laptop(tmp_path):
    """Qt restores a geometry larger than the screen at two thirds of the screen (861×480
    on 1280×720), too narrow for the toolbar; the window takes what the screen has."""
    ini = str(tmp_path / "settings.ini")
    for (width, height), step in (((1920, 1080), "save"), ((1280, 720), "restore")):
        run = subprocess.run([sys.executable, "-c", LAST_SIZE, ini, step], env=_screen_env(tmp_path, width, height),
                             capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout.strip().splitlines()[-1])
    x, y, w, h = result["frame"]
    assert result["area"] == [0, 0, 1280, 720]
    assert x >= 0 and y >= 0 and x + w <= 1280 and y + h <= 720, result  # on the screen
    assert w >= 1280 - 16 and h >= 720 - 40, result  # and all of it (less the title bar's room)
    assert not result["overflow"]  # every toolbar button in view


def test_a_long_review_reason_is_one_line_with_details_on_demand(qtbot):
    panel = MatcherPanel()
    qtbot.addWidget(panel)
    panel.resize(380, 520)
    panel.show()
    qtbot.waitExposed(panel)
    lines = [("femoral: matched, 0.120 mm (40 calls, 1.0 s)", "ok", False),
             (f"tibial: needs review — {LONG_REASON}, 0.900 mm (80 calls, 2.0 s)", "bad", True)]
    panel.show_poses(lines)
    assert panel.pose_summary.isVisible() and not panel.status.isVisible() and panel.details_button.isVisible()
    summary = panel.pose_summary.text().split("<br>")
    assert len(summary) == 2 and "(+2 more)" in summary[1] and "moved 6.2 mm" not in summary[1]
    width = panel.texts.viewport().width()
    bold = panel.pose_summary.font()
    bold.setBold(True)
    plain = panel.pose_summary.toolTip().splitlines()
    assert plain == [text for text, _, _ in lines]  # the whole text on hover
    tibial_line = summary[1].split("</span> ")[1].removesuffix("</b>").replace("&#x27;", "'")
    assert QFontMetrics(bold).horizontalAdvance(tibial_line) <= width  # one line, no wrap
    qtbot.mouseClick(panel.details_button, Qt.MouseButton.LeftButton)
    assert panel.status.isVisible() and not panel.pose_summary.isVisible()
    assert "moved 6.2 mm / 4.1° from the predicted pose" in panel.status.text()
    assert panel.details_button.text() == "Hide details"
    qtbot.mouseClick(panel.details_button, Qt.MouseButton.LeftButton)
    assert panel.pose_summary.isVisible() and not panel.status.isVisible()
    panel.show_message("Cancelled")  # a message is shown whole, without the button
    assert panel.status.isVisible() and not panel.details_button.isVisible() and not panel.pose_summary.isVisible()
    panel.show_poses([("femoral: matched", "ok", True)])
    assert panel.status.isVisible() and not panel.details_button.isVisible()


def put_truth(session, status=Status.MATCHED):
    for frame, by in session.project.settings["demo_truth"].items():
        for c, pose in by.items():
            session.project.poses[(int(frame), c)] = PoseRecord(np.asarray(pose, float), status=status)


def test_kinematics_curves_scroll_at_a_readable_size_or_open_in_a_window(window, demo, qtbot):
    window.open_project(demo)
    put_truth(window.session, Status.PLACED)  # placed, not matched: a long review reason
    window.presenters.kinematics.refresh_knee()
    panel = window.knee_panel
    panel.setParent(None)  # on its own, at a laptop dock's size
    qtbot.addWidget(panel)
    panel.resize(420, 320)
    panel.show()
    qtbot.waitExposed(panel)
    assert panel.canvas.height() >= PLOT_MIN_SIZE[1] and panel.canvas.width() >= PLOT_MIN_SIZE[0]
    assert panel.plot_area.verticalScrollBar().maximum() > 0  # scrolls instead of squeezing
    assert panel.status_line.isVisible() and "(+1 more)" in panel.status_line.text()
    assert not panel.status.isVisible()
    qtbot.mouseClick(panel.details_button, Qt.MouseButton.LeftButton)
    assert panel.status.isVisible() and "tibial placed by hand" in panel.status.text()
    qtbot.mouseClick(panel.window_button, Qt.MouseButton.LeftButton)
    curves = panel.curves_window
    assert curves is not None and curves.isVisible()
    qtbot.waitUntil(lambda: len(curves.axes) == 7, timeout=3000)
    area = curves.screen().availableGeometry()
    assert curves.width() <= area.width() and curves.height() <= area.height()
    curves.close()


def test_exports_start_in_the_projects_folder(window, demo, tmp_path):
    window.open_project(demo)
    assert window.knee._export_folder() == demo.parent
    session = window.session
    window.controller.set_project(session.project, None)  # an unsaved project: its images' folder is not used
    folder = window.knee._export_folder()
    images = {p.parent for p in session.image_paths(session.frames[0]) if p is not None}
    assert folder not in images and folder.is_dir()
    (tmp_path / "exports").mkdir()
    window.settings.setValue("export_dir", str(tmp_path / "exports"))  # where the last export went
    assert window.knee._export_folder() == tmp_path / "exports"


def test_export_dialog_writes_motion_files_with_the_frame_rate(window, demo, tmp_path, monkeypatch, dialogs):
    window.open_project(demo)
    put_truth(window.session)
    (tmp_path / "out").mkdir()
    given = {"fps": 0.0}

    def exec_(dialog):
        dialog.folder.setText(str(tmp_path / "out"))
        for key in ("poses", "kinematics"):
            dialog.checks[key].setChecked(False)
        for key in ("c3d", "mot", "trc", "xromm"):
            dialog.checks[key].setChecked(True)
        dialog.frame_rate.setValue(given["fps"])
        return QDialog.DialogCode.Accepted

    monkeypatch.setattr(ExportDialog, "exec", exec_)
    window.knee.export_results()
    assert len(dialogs["warning"]) == 1 and "frame rate" in dialogs["warning"][0][2]
    assert not list((tmp_path / "out").iterdir())
    given["fps"] = 30.0
    window.knee.export_results()
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["demo.c3d", "demo.trc", "demo_knee.mot",
                                                                     "demo_xromm.csv"]
    assert "Exported 4 files" in window.statusBar().currentMessage()
    assert exports.frame_rate(window.session) == 30.0 and window.isWindowModified()
    window.edit.undo_action.trigger()
    assert exports.frame_rate(window.session) is None


def test_import_dialog_keeps_the_frame_rate(qtbot, tmp_path):
    from fluorogui.gui.dialogs.import_dialog import ImportDialog
    from fluorogui.simulation.demo import build_demo_project

    build_demo_project(tmp_path, frames=2, image_size=96)
    dialog = ImportDialog()
    qtbot.addWidget(dialog)
    # a short screen scrolls the fields; the Import button stays outside the scrolling part
    assert dialog.height() <= dialog.screen().availableGeometry().height() - 60
    assert not dialog.form_area.isAncestorOf(dialog.buttons)
    assert dialog.fill_from_folder(tmp_path)
    dialog.frame_rate.setValue(24.0)
    dialog.accept()
    assert dialog.project is not None and dialog.project.settings["time"] == {"fps": 24.0, "source": "user"}
