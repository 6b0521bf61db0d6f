"""Check the built site against the code (``docs/build.sh`` runs it after sphinx-build).

* Every sub-command and every option of ``fluorogui --help`` (the parsers themselves,
  walked recursively) appears on the command-reference pages.
* The API pages name ``Session``, ``FrameResult`` and ``track``.

Exits 1 naming what is missing.
"""
from __future__ import annotations

import argparse
import html
import re
import sys
from pathlib import Path


def commands(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()):
    """(sub-command path, option strings) for the parser and every sub-parser under it."""
    options = [s for a in parser._actions for s in a.option_strings if s not in ("-h", "--help")]
    yield prefix, options
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from commands(sub, (*prefix, name))


def page_text(path: Path) -> str:
    text = re.sub(r"<[^>]+>", " ", path.read_text(encoding="utf-8"))
    text = html.unescape(text).replace("\u2011", "-").replace("\u2013", "--")
    return re.sub(r"\s+", " ", text)  # highlighted usage lines split words across tags


def main(site: Path) -> int:
    from fluorogui.cli import build_parser

    cli_pages = sorted((site / "cli").glob("*.html"))
    cli_text = "\n".join(page_text(p) for p in cli_pages)
    missing = []
    n_commands = n_options = 0
    for path, options in commands(build_parser()):
        n_commands += 1
        if path and not re.search(rf"fluorogui {' '.join(path)}\b", cli_text):
            missing.append(f"sub-command 'fluorogui {' '.join(path)}'")
        page = site / "cli" / f"{path[0]}.html" if path else None
        text = page_text(page) if page is not None and page.exists() else cli_text
        for option in options:
            n_options += 1
            if not re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", text):
                missing.append(f"option {option} of 'fluorogui {' '.join(path)}'".replace("  ", " "))
    api_text = "\n".join(page_text(p) for p in sorted((site / "api").glob("*.html")))
    for name in ("Session", "FrameResult", "track"):
        if not re.search(rf"\b{name}\b", api_text):
            missing.append(f"API name {name}")
    if missing:
        print("docs: the built site lacks:\n  " + "\n  ".join(missing), file=sys.stderr)
        return 1
    print(f"docs: {n_commands} commands and {n_options} options of `fluorogui --help` are on the "
          f"{len(cli_pages)} command pages; the API pages name Session, FrameResult and track", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "_build" / "html"))
