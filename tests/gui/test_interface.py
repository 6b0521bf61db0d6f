"""Interface fixes of issue 12: the raw pixel value under the cursor, Accept and Un-accept
as separate actions, Home/End and the component key, the complete shortcut list, About."""
import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PIL import Image  # noqa: E402
from PySide6.QtCore import QPoint, Qt  # noqa: E402
from PySide6.QtTest import QTest  # noqa: E402
from PySide6.QtWidgets import QApplication, QMessageBox  # noqa: E402

from fluorogui import __version__  # noqa: E402
from fluorogui.gui.pixel_value import RawPixels, format_value  # noqa: E402
from fluorogui.logs import log_file_path  # noqa: E402
from fluorogui.core.session import PoseRecord  # noqa: E402


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
    assert not window.accept_action.isEnabled() and not window.unaccept_action.isEnabled()  # only placed
    assert not window.matcher.accept_button.isEnabled()
    record = s.pose_record(name, 0)
    s.set_record(name, 0, PoseRecord(record.pose, None, status="matched"), "Matched by hand")
    assert window.accept_action.isEnabled() and not window.unaccept_action.isEnabled()
    assert window.matcher.accept_button.text() == "Accept"
    assert window.accept_pose() and s.pose_record(name, 0).reviewed
    assert window.matcher.accept_button.text() == "Un-accept"
    assert not window.accept_action.isEnabled() and window.unaccept_action.isEnabled()
    assert not window.accept_pose() and s.pose_record(name, 0).reviewed  # a second Accept is no toggle
    assert "already accepted" in window.statusBar().currentMessage()
    window.matcher.accept_button.click()  # the button now says Un-accept and does it
    assert not s.pose_record(name, 0).reviewed
    assert window.matcher.accept_button.text() == "Accept" and window.accept_action.isEnabled()
    assert not window.unaccept_pose()


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
    assert c.component == second and window.component_combo.currentText() == second
    QTest.keyClick(handle, "k")
    assert c.component == first


def test_shortcut_list_is_complete(window):
    rows = dict(window.shortcut_rows())
    for name, keys in (("Move point", "M"), ("Undo", "Ctrl+Z"), ("Redo", "Ctrl+Shift+Z"), ("Accept pose", "Ctrl+Return"),
                       ("Un-accept pose", "Ctrl+Shift+Return"), ("First frame", "Home"), ("Last frame", "End"),
                       ("Next component", "K"), ("Keyboard shortcuts", "F1"), ("Fit images", "F")):
        assert name in rows and rows[name].startswith(keys), (name, rows.get(name))
    dialog = window.show_shortcuts()
    text = dialog.browser.toPlainText()
    assert "Ctrl+Shift+Z" in text and "Move point" in text and "<table" in window.shortcuts_html()
    dialog.close()


def test_about_shows_version_and_log_file(window, monkeypatch):
    shown = []
    monkeypatch.setattr(QMessageBox, "about", lambda parent, title, text: shown.append(text))
    window.about_action.trigger()
    assert __version__ in shown[0] and str(log_file_path()) in shown[0]


def test_version_comes_from_the_package_metadata():
    from importlib.metadata import version

    assert __version__ == version("fluorogui")


def test_quick_start_page_is_shipped_with_the_shortcuts(window):
    dialog = window.show_quick_start()
    text = dialog.browser.toPlainText()
    assert "Quick start" in text or "quick start" in text
    assert "Un-accept" in text and "Ctrl+Shift+Z" in text  # the live shortcut table is filled in
    dialog.close()
