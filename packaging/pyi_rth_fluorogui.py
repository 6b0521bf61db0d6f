"""Run-time hook of the standalone build: pyvistaqt reaches Qt through qtpy, which must
pick the PySide6 that is bundled (not look for PyQt first)."""
import os

os.environ.setdefault("QT_API", "pyside6")
