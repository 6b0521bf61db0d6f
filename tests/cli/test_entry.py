"""The entry point (``fluorogui.__main__.main``) hands sub-commands and options to the
command line; the console script runs it. The ``python -m fluorogui`` run in a fresh
interpreter, proving that no Qt is imported, is tests/cli/test_cli.py's
test_cli_runs_as_a_module_without_qt."""
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fluorogui import __version__
from fluorogui.__main__ import main


def test_version(capsys):
    with pytest.raises(SystemExit) as exit_:  # argparse's version action ends the command
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"fluorogui {__version__}"


def test_entry_reports_bad_usage_in_one_line(capsys):
    assert main(["match", "--camera", "x"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "required" in err


def test_console_script_runs_the_entry():
    """The installed ``fluorogui`` script (its own process on purpose: that is what it is)."""
    script = Path(sys.executable).with_name("fluorogui")
    if not script.exists():
        script = shutil.which("fluorogui")
    if script is None:
        pytest.skip("fluorogui console script is not installed")
    proc = subprocess.run([str(script), "--version"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"fluorogui {__version__}"


def test_a_reader_that_stops_reading_ends_the_command_quietly(monkeypatch, capsys):
    """``fluorogui track P --json | head -1`` said "internal error: BrokenPipeError"; it now
    stops quietly with the shell's code for a broken pipe (128 + SIGPIPE)."""
    from fluorogui.cli import main, track

    def reader_gone(args):
        raise BrokenPipeError(32, "Broken pipe")  # what print() raises once ``head`` has exited

    monkeypatch.setattr(track, "run", reader_gone)
    assert main(["track", "any.fluoro"]) == 141
    assert capsys.readouterr().err == ""
