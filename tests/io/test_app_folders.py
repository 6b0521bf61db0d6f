"""The app's folders (``fluorogui.logs``): where the operating system expects them
(platformdirs; Linux's XDG variables here), one folder for all with FLUOROGUI_DATA_DIR,
and the log file written where ``log_file_path`` says."""
from __future__ import annotations

import logging
import sys

import pytest

from fluorogui import logs


@pytest.fixture
def no_override(monkeypatch):
    monkeypatch.delenv(logs.DATA_DIR_ENV, raising=False)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the XDG variables are Linux's")
def test_linux_folders_follow_the_xdg_variables(no_override, monkeypatch, tmp_path):
    for name in ("DATA", "STATE", "CACHE"):
        monkeypatch.setenv(f"XDG_{name}_HOME", str(tmp_path / name.lower()))
    assert logs.data_dir() == tmp_path / "data" / "fluorogui"
    assert logs.log_file_path() == tmp_path / "state" / "fluorogui" / "log" / "fluorogui.log"
    assert logs.cache_dir() == tmp_path / "cache" / "fluorogui"


def test_folders_are_the_platforms(no_override, monkeypatch):
    import platformdirs

    monkeypatch.setattr(platformdirs, "user_data_dir", lambda app, appauthor: f"/data-of/{app}/{appauthor}")
    monkeypatch.setattr(platformdirs, "user_log_dir", lambda app, appauthor: f"/logs-of/{app}/{appauthor}")
    monkeypatch.setattr(platformdirs, "user_cache_dir", lambda app, appauthor: f"/cache-of/{app}/{appauthor}")
    assert str(logs.data_dir()).replace("\\", "/") == "/data-of/fluorogui/False"
    assert str(logs.log_dir()).replace("\\", "/") == "/logs-of/fluorogui/False"
    assert str(logs.cache_dir()).replace("\\", "/") == "/cache-of/fluorogui/False"


def test_one_folder_for_all_with_the_override(monkeypatch, tmp_path):
    monkeypatch.setenv(logs.DATA_DIR_ENV, str(tmp_path / "portable"))
    assert logs.data_dir() == tmp_path / "portable"
    assert logs.log_file_path() == tmp_path / "portable" / "logs" / "fluorogui.log"
    assert logs.cache_dir() == tmp_path / "portable" / "cache"


def test_the_log_is_written_where_it_is_said_to_be(monkeypatch, tmp_path):
    monkeypatch.setenv(logs.DATA_DIR_ENV, str(tmp_path))
    root = logging.getLogger()
    level = root.level
    try:
        assert logs.setup_logging() == logs.log_file_path()
        logging.getLogger("fluorogui.test").warning("written to the log file")
        for handler in root.handlers:
            handler.flush()
        assert "written to the log file" in logs.log_file_path().read_text(encoding="utf-8")
    finally:
        for handler in [h for h in root.handlers if getattr(h, "_fluorogui", False)]:
            root.removeHandler(handler)
            handler.close()
        root.setLevel(level)
