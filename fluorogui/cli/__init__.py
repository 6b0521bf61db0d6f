"""The headless command line: one module per command (``add_parser`` + ``run``) over the workflow; never imports Qt."""
from fluorogui.cli.entry import build_parser, main

__all__ = ["build_parser", "main"]
