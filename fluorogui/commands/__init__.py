"""The workflow's command-line sub-commands, one module per group, each a thin layer over
``fluorogui.workflow`` (the functions the desktop app calls too)."""
from fluorogui.commands import knee, sessions, tracking


def add_parsers(sub) -> None:
    sessions.add_parsers(sub)
    tracking.add_parsers(sub)
    tracking.add_batch_parser(sub)
    knee.add_parsers(sub)
