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
