"""Entry point: `fluorogui` / `python -m fluorogui`.

With no arguments, or a single project file, start the desktop app; otherwise hand the
arguments to the headless command line. Qt is imported only for the desktop app.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Sequence

PROJECT_SUFFIX = ".fluoro"


def _is_project_file_argument(argv: Sequence[str]) -> bool:
    if len(argv) != 1 or argv[0].startswith("-"):
        return False
    arg = argv[0]
    return arg.lower().endswith(PROJECT_SUFFIX) or os.path.isfile(arg)


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
