"""Files the app reads at run time that are not Python code, shipped as package data:
toolbar and application icons (``icons/``) and the quick-start page (``quickstart.html``)."""
from __future__ import annotations

from pathlib import Path

RESOURCE_DIR = Path(__file__).resolve().parent
ICON_DIR = RESOURCE_DIR / "icons"


def resource_path(name: str) -> Path:
    """The path of a shipped resource file by name (relative to this package)."""
    return RESOURCE_DIR / name
