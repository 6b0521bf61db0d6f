"""The app's open path on nasty projects: one dialog naming the file, the session unchanged."""
from __future__ import annotations

import pytest

pytest.importorskip("pytestqt")
from nasty_projects import FIXTURE, nasty_projects  # noqa: E402
from PySide6.QtCore import QSettings  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402


@pytest.fixture()
def window(qtbot, tmp_path, monkeypatch):
    from fluorogui.gui.dialogs.missing_files import MissingFiles
    from fluorogui.gui.main_window import MainWindow

    monkeypatch.setenv("FLUOROGUI_DATA_DIR", str(tmp_path / "appdata"))
    warnings = []
    monkeypatch.setattr(QMessageBox, "warning", lambda *a, **k: warnings.append(a) or QMessageBox.StandardButton.Ok)
    monkeypatch.setattr(MissingFiles, "ask", lambda self, box: None)  # "Locate the model?": cancelled
    w = MainWindow(settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat), with_3d=False)
    qtbot.addWidget(w)
    w.warnings = warnings
    yield w
    w.controller.session.history.set_clean()
    w.controller.close()


def test_every_nasty_project_gives_one_dialog_and_keeps_the_session(window, tmp_path):
    good = tmp_path / "good.fluoro"
    good.write_text(FIXTURE.read_text())
    assert window.open_project(good, ask=False)
    project, path = window.controller.project, window.controller.path
    for k, (name, text) in enumerate(nasty_projects()):
        bad = tmp_path / f"{name}.fluoro"
        bad.write_text(text, encoding="utf-8")
        assert not window.open_project(bad, ask=False), name
        assert len(window.warnings) == k + 1, name
        message = window.warnings[-1][2]
        assert message.startswith(f"{bad}: ") and "\n" not in message, message
        assert window.controller.project is project and window.controller.path == path
    assert not (tmp_path / "bad.fluoro.lock").exists()
