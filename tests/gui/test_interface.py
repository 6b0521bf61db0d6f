"""Interface fixes of issue 12: the raw pixel value under the cursor, Accept and Un-accept
as separate actions, Home/End and the component key, the complete shortcut list, About."""
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PIL import Image  # noqa: E402
from PySide6.QtCore import QPoint, Qt  # noqa: E402
from PySide6.QtTest import QTest  # noqa: E402
from PySide6.QtWidgets import QApplication, QMessageBox  # noqa: E402

from fluorogui import __version__  # noqa: E402
from fluorogui.core.records import PoseRecord  # noqa: E402
from fluorogui.gui.panels.pixel_value import RawPixels, format_value  # noqa: E402
from fluorogui.logs import log_file_path  # noqa: E402


def _hover(qtbot, panel, u, v):
    """Move the mouse over image pixel (u, v) of a panel."""
    pos = panel.mapFromScene(u, v)
    qtbot.mouseMove(panel.viewport(), QPoint(pos.x(), pos.y()))
    return panel.mapToScene(pos)


def test_status_bar_shows_the_value_stored_in_the_demo_file(window, demo, qtbot):
    window.open_project(demo)
    window.resize(1280, 720)
    window.show()
    qtbot.waitExposed(window)
    s, panel = window.session, window.panels[0]
    path = s.image_path(0, 0)
    stored = np.array(Image.open(path))  # an independent reader (Pillow) of the demo's PNG
    panel.fit()
    h, w = stored.shape
    seen = set()
    for u, v in ((w * 0.5, h * 0.5), (w * 0.3, h * 0.6), (w * 0.1, h * 0.1)):
        scene = _hover(qtbot, panel, u, v)
        col, row = int(np.floor(scene.x() + 0.5)), int(np.floor(scene.y() + 0.5))
        assert window.cursor_label.text().endswith(f"value {int(stored[row, col])}")
        seen.add(int(stored[row, col]))
    assert len(seen) > 1 and max(seen) > 1  # not only 0 and 1 (the scaled image)


def test_raw_value_of_the_real_8_bit_tiff(shared_data):
    path = shared_data / "biplane-tka" / "cam2" / "000802.tif"
    stored = np.array(Image.open(path))
    rows, cols = np.nonzero(stored == 60)
    raw = RawPixels()
    assert format_value(raw.value_at(path, float(cols[0]), float(rows[0]), stored.shape)) == "60"
    assert raw.value_at(path, -3.0, 5.0, stored.shape) is None  # outside the image
    assert raw.value_at(path, 5.0, 5.0, (10, 10)) is None  # not the image on screen


@pytest.mark.parametrize("suffix", [".tif", ".png"])
def test_raw_value_of_a_16_bit_file(tmp_path, suffix):
    import cv2
    import tifffile

    known = (np.arange(40 * 30, dtype=np.uint16).reshape(30, 40) * 50)  # values up to 59950
    path = tmp_path / f"img{suffix}"
    tifffile.imwrite(path, known) if suffix == ".tif" else cv2.imwrite(str(path), known)
    raw = RawPixels()
    assert raw.value_at(path, 39.0, 29.0, known.shape) == 59950
    assert raw.value_at(path, 12.4, 7.6, known.shape) == known[8, 12]


def test_format_value():
    assert format_value(np.uint16(60000)) == "60000"
    assert format_value(np.float32(0.25)) == "0.25"
    assert format_value(np.float64(12.0)) == "12"
    assert format_value(np.array([1, 2, 3], dtype=np.uint8)) == "1,2,3"
    assert format_value(float("nan")) == "–"


def test_accept_and_unaccept_are_separate_labelled_actions(window, demo):
    window.open_project(demo)
    c, s = window.controller, window.session
    name = c.component
    accept, unaccept = window.actions_by_id["match.accept"], window.actions_by_id["match.unaccept"]
    assert not accept.isEnabled() and not unaccept.isEnabled()  # only placed
    assert not window.matcher.accept_button.isEnabled()
    record = s.pose_record(name, 0)
    s.set_record(name, 0, PoseRecord(record.pose, None, status="matched"), "Matched by hand")
    assert accept.isEnabled() and not unaccept.isEnabled()
    assert window.matcher.accept_button.text() == "Accept"
    assert window.review.accept_pose() and s.pose_record(name, 0).reviewed
    assert window.matcher.accept_button.text() == "Un-accept"
    assert not accept.isEnabled() and unaccept.isEnabled()
    assert not window.review.accept_pose() and s.pose_record(name, 0).reviewed  # a second Accept is no toggle
    assert "already accepted" in window.statusBar().currentMessage()
    window.matcher.accept_button.click()  # the button now says Un-accept and does it
    assert not s.pose_record(name, 0).reviewed
    assert window.matcher.accept_button.text() == "Accept" and accept.isEnabled()
    assert not window.review.unaccept_pose()


def test_home_end_and_the_component_key(window, demo, qtbot):
    window.open_project(demo)
    window.show()
    window.activateWindow()
    qtbot.waitActive(window)  # shortcuts reach the active window only
    c = window.controller
    window.panels[0].setFocus()
    handle = window.windowHandle()  # key events through the window, where shortcuts are matched
    qtbot.waitUntil(lambda: QApplication.focusWindow() is handle and window.panels[0].hasFocus())
    QTest.keyClick(handle, Qt.Key.Key_End)
    assert c.frame == 2
    QTest.keyClick(handle, Qt.Key.Key_Home)
    assert c.frame == 0
    first, second = c.components()
    assert c.component == first
    QTest.keyClick(handle, "k")
    assert c.component == second and window.model.component_combo.currentText() == second
    QTest.keyClick(handle, "k")
    assert c.component == first


def test_shortcut_list_is_complete(window):
    rows = dict(window.help.shortcut_rows())
    for name, keys in (("Move point", "M"), ("Undo", "Ctrl+Z"), ("Redo", "Ctrl+Shift+Z"),
                       ("Accept pose", "Ctrl+Return"), ("Un-accept pose", "Ctrl+Shift+Return"),
                       ("First frame", "Home"), ("Last frame", "End"),
                       ("Next component", "K"), ("Keyboard shortcuts", "F1"), ("Fit images", "F")):
        assert name in rows and rows[name].startswith(keys), (name, rows.get(name))
    assert all(len(keys.split(" or ")) == len(set(keys.split(" or "))) for keys in rows.values())  # no repeats
    dialog = window.help.show_shortcuts()
    text = dialog.browser.toPlainText()
    assert "Ctrl+Shift+Z" in text and "Move point" in text and "<table" in window.help.shortcuts_html()
    dialog.close()


def test_about_shows_version_and_log_file(window, monkeypatch):
    shown = []
    monkeypatch.setattr(QMessageBox, "about", lambda parent, title, text: shown.append(text))
    window.actions_by_id["help.about"].trigger()
    assert __version__ in shown[0] and str(log_file_path()) in shown[0]


def test_version_comes_from_the_package_metadata():
    from importlib.metadata import version

    assert __version__ == version("fluorogui")


def test_quick_start_page_is_shipped_with_the_shortcuts(window):
    dialog = window.help.show_quick_start()
    text = dialog.browser.toPlainText()
    assert "Quick start" in text or "quick start" in text
    assert "Un-accept" in text and "Ctrl+Shift+Z" in text  # the live shortcut table is filled in
    dialog.close()


def _path_points(path):
    return np.array([(path.elementAt(i).x, path.elementAt(i).y) for i in range(path.elementCount())])


def test_an_erased_stretch_is_drawn_as_a_gap(qtbot):
    from fluorogui.gui.panels.image_panel import ImagePanel

    panel = ImagePanel(0)
    qtbot.addWidget(panel)
    panel.set_image(np.zeros((200, 200), dtype=np.uint8))
    angles = np.linspace(0, 2 * np.pi, 80, endpoint=False)
    circle = np.column_stack([100 + 60 * np.cos(angles), 100 + 60 * np.sin(angles)])
    panel.set_outline("femoral", circle, key=(0, 0, "femoral"))
    items = panel._components["femoral"]
    assert items.gap_count == 0 and items.gap_line.path().isEmpty()
    kept = np.r_[0:30, 50:80]  # points 30..49 erased: a quarter of the circle
    panel.set_outline("femoral", circle[kept], key=(0, 0, "femoral"))
    assert items.gap_count == 1
    middle = np.array([100 + 60 * np.cos(angles[40]), 100 + 60 * np.sin(angles[40])])  # where points were erased
    solid, dashed = _path_points(items.spline.path()), _path_points(items.gap_line.path())
    assert np.linalg.norm(solid - middle, axis=1).min() > 20  # no solid line across the gap
    assert np.linalg.norm(dashed - middle, axis=1).min() < 10  # the dashed chord is there instead
    assert np.linalg.norm(solid - circle[10], axis=1).min() < 1  # the kept stretch is drawn solid


def test_selected_point_marker_is_cleared_on_another_frame(window, demo):
    window.open_project(demo)
    panel = window.panels[0]
    if panel.outline(window.controller.component) is None:
        angles = np.linspace(0, 2 * np.pi, 40, endpoint=False)
        panel.set_outline(window.controller.component, np.column_stack([200 + 50 * np.cos(angles),
                                                                         200 + 50 * np.sin(angles)]), (0, 0, "x"))
    panel.tools.select(3)
    panel.tools.update_highlight()
    assert panel.selected_point() == 3
    window.review.step_frame(1)
    assert panel.selected_point() is None


def test_eta_follows_the_recent_frames_not_the_first():
    from fluorogui.gui.eta import Eta, describe

    eta = Eta(total=4)
    eta._last = (0.0, 0.0)
    # the complaint: a 2 s first frame, then 20 s frames; the plain average said 2 s left at 1/4
    assert eta.update(1, now=2.0) == pytest.approx(6.0)
    left = eta.update(2, now=22.0)  # moving average 0.4*20 + 0.6*2 = 9.2 s per frame
    assert left == pytest.approx(2 * 9.2)
    left = eta.update(3, now=42.0)  # 0.4*20 + 0.6*9.2 = 13.52
    assert left == pytest.approx(13.52)
    assert describe(None) == "" and describe(0.2) == "under a second left"
    assert describe(40) == "about 40 s left" and describe(180) == "about 3 min left"


def test_save_dialog_starts_beside_the_images_never_in_the_data_folder(window, tmp_path, monkeypatch):
    from PySide6.QtWidgets import QFileDialog

    from fluorogui.gui.actions.files import app_data_dir

    assert window.open_demo(ask=False)  # the demo lives in the app's data folder
    data = app_data_dir().resolve()
    assert data in window.controller.path.resolve().parents
    monkeypatch.setenv("HOME", str(tmp_path))
    start = window.files.default_save_dir().resolve()
    assert start != data and data not in start.parents
    asked = []
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (asked.append(a[2]), ("", ""))[1])
    assert not window.files.save_as()
    assert data not in Path(asked[0]).resolve().parents
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (asked.append(a[2]), ("", ""))[1])
    assert not window.open_project()  # File → Open after the demo: not in the demo's folder either
    assert Path(asked[1]).resolve() != data and data not in Path(asked[1]).resolve().parents


def test_save_dialog_starts_in_the_images_folder(window, demo):
    window.open_project(demo)
    window.controller.session.path = None  # an imported session: no file yet
    assert window.files.default_save_dir().resolve() == demo.parent.resolve()


def test_no_session_and_a_missing_image_leave_a_hint(window, demo):
    assert "File → Open" in window.panels[0].placeholder
    window.open_project(demo)
    assert window.panels[0].placeholder == ""
    path = window.session.image_path(1, 0)
    path.unlink()
    window.review.step_frame(1)
    assert window.panels[0].image() is None and path.name in window.panels[0].placeholder


def test_tool_hint_in_the_status_bar_and_tooltips_on_every_tool_button(window):
    from PySide6.QtWidgets import QToolBar, QToolButton

    from fluorogui.gui.panels.image_panel import Tool

    window.edit.set_tool(Tool.ERASE)
    assert window.edit.tool_label.text().startswith("Erase (E): Brush away")
    bar = window.findChild(QToolBar, "mainToolbar")
    buttons = [b for b in bar.findChildren(QToolButton) if b.defaultAction() is not None]
    assert len(buttons) > 10
    for button in buttons:
        action = button.defaultAction()
        assert action.toolTip() and action.toolTip() != action.text().replace("&", ""), action.text()


def test_keyboard_focus_is_ringed(window, qtbot):
    window.show()
    window.activateWindow()
    qtbot.waitActive(window)
    button = window.matcher.run_button
    button.setFocus()
    qtbot.waitUntil(lambda: window.focus_frame.widget() is button)
    assert window.focus_frame.isVisible()
    window.panels[1].setFocus()
    qtbot.waitUntil(lambda: window.focus_frame.widget() is window.panels[1])


def test_the_window_fits_a_small_laptop_screen(window):
    hint = window.minimumSizeHint()
    assert hint.width() <= 1024 and hint.height() <= 700  # docks scroll instead of forcing the size
    window.resize(1024, 700)
    assert window.size().height() <= 700
