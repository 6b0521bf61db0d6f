"""The ``fluorogui`` command line: the parser of every command (one module each, in the
order of ``COMMANDS``) and ``main``, which runs one command line.

Every failure ends in one line on stderr and a non-zero exit (2 for bad input, 1 for
an internal error, its traceback in the log file), never a traceback. Never imports Qt.
"""
from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from fluorogui import __version__
from fluorogui.cli import (
    batch,
    bench,
    calibrate,
    demo,
    export,
    find,
    import_,
    kinematics,
    match,
    track,
    validate,
)
from fluorogui.cli.common import Parser, UsageError, native_stderr_to_log
from fluorogui.cli.inputs import input_warnings_on_stderr

#: the commands in the order ``fluorogui --help`` lists them; each module has
#: ``add_parser(sub) -> parser`` and ``run(args) -> exit status``
COMMANDS = (match, validate, bench, demo, import_, find, track, batch, export, kinematics, calibrate)


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="fluorogui", description="Pose of knee-implant components from biplane fluoroscopy.")
    p.add_argument("--version", action="version", version=f"fluorogui {__version__}")
    p.add_argument("--verbose", action="store_true",
                   help="also print warnings of the libraries (VTK, image readers) and tracebacks on the terminal")
    sub = p.add_subparsers(dest="command", parser_class=Parser)
    for command in COMMANDS:
        command.add_parser(sub).set_defaults(run=command.run)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; every failure ends in one line on stderr: exit 2 for bad input (the
    line names the file or option), 1 for an internal error (its traceback in the log file)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    verbose = "--verbose" in argv
    argv = [a for a in argv if a != "--verbose"]  # allowed anywhere on the line
    from fluorogui.logs import setup_logging

    log_path = setup_logging(verbose=verbose)
    try:
        with native_stderr_to_log(None if verbose else log_path), input_warnings_on_stderr():
            return _run(argv)
    except UsageError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fluorogui: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of stdout stopped (``| head``): stop quietly, as cat does
        try:  # the exit's flush of what is left has nowhere to go
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return 141
    except Exception as exc:  # noqa: BLE001 - the CLI never shows a traceback
        from fluorogui.core.projection.geometry import GeometryError
        from fluorogui.core.projection.mesh import MeshError
        from fluorogui.io.errors import InputError
        from fluorogui.logs import log_exception

        if isinstance(exc, OSError) and exc.filename and not isinstance(exc, InputError):
            from fluorogui.io.errors import describe_os_error

            exc = InputError(exc.filename, describe_os_error(exc))  # a path we could not read or write
        if isinstance(exc, InputError):
            print(f"fluorogui: error: {exc}", file=sys.stderr)
            return 2
        logged = log_exception(f"fluorogui {' '.join(argv)[:500]}")
        if isinstance(exc, (GeometryError, MeshError, ValueError, KeyError)):
            if isinstance(exc, KeyError):
                exc = exc.args[0] if exc.args else exc
            print(f"fluorogui: error: {' '.join(str(exc).split())}", file=sys.stderr)
            return 2
        where = f"; details in {logged}" if logged else ""
        print(f"fluorogui: internal error: {type(exc).__name__}: {' '.join(str(exc).split())[:300]}{where}",
              file=sys.stderr)
        return 1


def _run(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    if not getattr(args, "command", None):
        build_parser().print_help()
        return 0
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
