"""The placeholder main window: builds, opens a project, refuses a bad file without closing."""
import shutil
from pathlib import Path

import pytest

pytest.importorskip("pytestqt")
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from fluorogui.gui.app import MainWindow  # noqa: E402

FIXTURE = Path(__file__).resolve().parents[1] / "io" / "data" / "project_v2.fluoro"


def test_window_opens_a_project_and_survives_a_corrupt_one(qtbot, tmp_path, monkeypatch):
    warnings = []
    monkeypatch.setattr(QMessageBox, "warning", lambda *a, **k: warnings.append(a))
    window = MainWindow()
    qtbot.addWidget(window)
    assert window.windowTitle().startswith("fluorogui")

    good = tmp_path / "session.fluoro"
    shutil.copy(FIXTURE, good)
    assert window.open_project(good)
    assert "session.fluoro" in window.windowTitle()
    opened = window.project

    bad = tmp_path / "broken.fluoro"
    bad.write_text('{"format": "fluorogui-project", "schema_version": 2, "views": [')
    assert not window.open_project(bad)
    assert len(warnings) == 1 and "broken.fluoro" in warnings[0][2]
    assert window.project is opened  # a failed load leaves the open project untouched


def test_window_has_title_two_image_panels_and_file_menu(qtbot):
    window = MainWindow()
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    assert window.windowTitle() == "fluorogui"
    assert [panel.title for panel in window.image_panels] == ["View 1", "View 2"]
    assert all(not panel.pixmap().isNull() for panel in window.image_panels)
    assert window.statusBar().currentMessage()
    file_menu = window.menuBar().actions()[0].menu()
    labels = [action.text().replace("&", "") for action in file_menu.actions() if action.text()]
    assert labels == ["Open…", "Quit"]
    assert window.quit_action.shortcut().toString() == "Ctrl+Q"


def test_file_open_with_corrupt_file_warns_and_window_stays_usable(qtbot, tmp_path, monkeypatch):
    from PySide6.QtWidgets import QFileDialog

    bad = tmp_path / "corrupt.fluoro"
    bad.write_bytes(b"\x00\xffnot a project\x89PNG")
    warnings = []
    monkeypatch.setattr(QMessageBox, "warning", lambda *a, **k: warnings.append(a) or QMessageBox.StandardButton.Ok)
    monkeypatch.setattr(QMessageBox, "critical", lambda *a, **k: warnings.append(a) or QMessageBox.StandardButton.Ok)
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (str(bad), "fluorogui projects (*.fluoro)"))

    window = MainWindow()
    qtbot.addWidget(window)
    window.show()
    window.open_action.trigger()

    assert len(warnings) == 1 and "corrupt.fluoro" in warnings[0][2]
    assert window.isVisible() and window.project is None
    assert window.windowTitle() == "fluorogui"
    assert "corrupt.fluoro" in window.statusBar().currentMessage()
    window.open_action.trigger()  # the menu still works after the failure
    assert len(warnings) == 2
