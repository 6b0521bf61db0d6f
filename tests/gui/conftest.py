"""Shared fixtures of the GUI tests: generated demo sessions (copied per test), message
boxes recorded instead of shown, and a main window without the 3D panel."""
import shutil

import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import QSettings  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from fluorogui.simulation.demo import build_demo_project  # noqa: E402


@pytest.fixture(scope="session")
def demo_source(tmp_path_factory):
    """A small demo: three frames of 512 px (quick)."""
    return build_demo_project(tmp_path_factory.mktemp("demo"), frames=3, image_size=512)


@pytest.fixture(scope="session")
def fine_demo_source(tmp_path_factory):
    """The demo's four frames at 768 px: fine enough for the 0.05 mm / 0.05 deg checks."""
    return build_demo_project(tmp_path_factory.mktemp("fine_demo"), frames=4, image_size=768)


def _copy(source, target):
    shutil.copytree(source.parent, target)
    return target / source.name


@pytest.fixture()
def demo(demo_source, tmp_path):
    return _copy(demo_source, tmp_path / "demo")


@pytest.fixture()
def fine_demo(fine_demo_source, tmp_path):
    return _copy(fine_demo_source, tmp_path / "fine_demo")


@pytest.fixture()
def dialogs(monkeypatch):
    """Record message boxes instead of blocking; questions answer from ``answers``."""
    seen = {"warning": [], "question": [], "information": [], "answers": []}

    def warning(*args, **kwargs):
        seen["warning"].append(args)
        return QMessageBox.StandardButton.Ok

    def information(*args, **kwargs):
        seen["information"].append(args)
        return QMessageBox.StandardButton.Ok

    def question(*args, **kwargs):
        seen["question"].append(args)
        return seen["answers"].pop(0) if seen["answers"] else QMessageBox.StandardButton.Discard

    monkeypatch.setattr(QMessageBox, "warning", warning)
    monkeypatch.setattr(QMessageBox, "information", information)
    monkeypatch.setattr(QMessageBox, "question", question)

    def ask(missing, box):  # the main window's own modal boxes (Locate a missing model): cancelled
        seen["question"].append((box.windowTitle(), box.text()))
        return None

    from fluorogui.gui.dialogs.missing_files import MissingFiles

    monkeypatch.setattr(MissingFiles, "ask", ask)
    return seen


def make_window(qtbot, ini):
    from fluorogui.gui.main_window import MainWindow

    w = MainWindow(settings=QSettings(str(ini), QSettings.Format.IniFormat), with_3d=False)
    qtbot.addWidget(w)
    return w


@pytest.fixture()
def window(qtbot, tmp_path, monkeypatch, dialogs):
    monkeypatch.setenv("FLUOROGUI_DATA_DIR", str(tmp_path / "appdata"))
    w = make_window(qtbot, tmp_path / "settings.ini")
    yield w
    w.runner.cancel()
    w.runner.wait()
    w.controller.session.history.set_clean()
    w.controller.close()
