"""Entry point: `fluorogui` / `python -m fluorogui`.

With no arguments, or a single project file or folder, start the desktop app; otherwise hand the
arguments to the headless command line. Qt is imported only for the desktop app.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Sequence

PROJECT_SUFFIX = ".fluoro"


def _is_project_file_argument(argv: Sequence[str]) -> bool:
    """One argument that is a project file, another file, or a folder (to import) opens
    the window; a folder named like a sub-command stays a sub-command."""
    if len(argv) != 1 or argv[0].startswith("-"):
        return False
    arg = argv[0]
    if arg.lower().endswith(PROJECT_SUFFIX) or os.path.isfile(arg):
        return True
    return os.path.isdir(arg) and arg not in _command_names()


def _command_names() -> set[str]:
    from fluorogui import cli

    parser = cli.build_parser()
    return {name for action in parser._subparsers._group_actions for name in action.choices}


def main(argv: Sequence[str] | None = None) -> int:
    """Dispatch to the desktop app or the CLI; return the process exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or _is_project_file_argument(args):
        from fluorogui.gui.app import run_app

        return run_app(args[0] if args else None)
    from fluorogui import cli

    return cli.main(args)


if __name__ == "__main__":
    sys.exit(main())
