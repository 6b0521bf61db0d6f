"""`python -m fluorogui` dispatches: sub-commands go to the CLI without importing Qt."""
import subprocess
import sys

from fluorogui import __version__


def test_version_without_qt():
    code = ("import sys; from fluorogui.__main__ import main\n"
            "try:\n    main(['--version'])\nexcept SystemExit as e:\n    pass\n"
            "assert 'PySide6' not in sys.modules\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert f"fluorogui {__version__}" in proc.stdout


def test_module_entry_reports_bad_usage_in_one_line():
    proc = subprocess.run([sys.executable, "-m", "fluorogui", "match", "--camera", "x"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "required" in proc.stderr


def test_python_dash_m_version():
    proc = subprocess.run([sys.executable, "-m", "fluorogui", "--version"], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"fluorogui {__version__}"


def test_console_script_matches_python_dash_m():
    import shutil
    from pathlib import Path

    script = Path(sys.executable).with_name("fluorogui")
    if not script.exists():
        script = shutil.which("fluorogui")
    if script is None:
        import pytest
        pytest.skip("fluorogui console script is not installed")
    proc = subprocess.run([str(script), "--version"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"fluorogui {__version__}"
