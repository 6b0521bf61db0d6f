"""A component whose mesh file is missing or unreadable: a dialog says so and offers
*Locate…* to point the session at the file where it is now (``Session.relink_mesh``, one
undoable step). Its stale 3D model and overlays are cleared by ``SessionView``.
``MissingFiles`` is given the controller, the ``Notices`` and where file dialogs start when
the missing file's folder is gone.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QObject
from PySide6.QtWidgets import QFileDialog, QMessageBox

from fluorogui.gui.notices import Notices
from fluorogui.io.errors import InputError
from fluorogui.io.meshes.read import MESH_SUFFIXES

MESH_FILTER = f"Surface models ({' '.join('*' + s for s in sorted(MESH_SUFFIXES))});;All files (*)"


class MissingFiles(QObject):
    """Asking a main window's user where a missing model file is now."""

    def __init__(self, controller, notices: Notices, *, default_dir: Callable[[], Path]) -> None:
        super().__init__(notices.parent_widget)
        self.controller = controller
        self.notices = notices
        self._default_dir = default_dir

    def offer_locate(self, name: str, error: InputError) -> bool:
        """Say a component's model cannot be loaded and offer *Locate…*; True if relinked."""
        self.notices.error(str(error))
        parent = self.notices.parent_widget
        box = QMessageBox(QMessageBox.Icon.Warning, "Model file not found",
                          f"The {name} model cannot be loaded:\n{error}\n\nLocate the file where it is now?",
                          QMessageBox.StandardButton.Cancel, parent)
        locate = box.addButton("Locate…", QMessageBox.ButtonRole.AcceptRole)
        box.setDefaultButton(locate)
        if self.ask(box) is not locate:
            return False
        start = str(Path(error.path).parent if Path(error.path).parent.is_dir() else self._default_dir())
        path, _ = QFileDialog.getOpenFileName(parent, f"Locate the {name} model", start, MESH_FILTER)
        return bool(path) and self.relink_model(name, path)

    def ask(self, box: QMessageBox):
        """Show a dialog and return the button clicked (tests replace this)."""
        box.exec()
        return box.clickedButton()

    def relink_model(self, name: str, path) -> bool:
        try:
            self.controller.session.relink_mesh(name, path)
        except InputError as exc:
            self.notices.warn("Cannot use this model", str(exc))
            return False
        self.notices.status(f"The {name} model is now {path}", 8000)
        return True

    def job_error(self, title: str, exc: Exception) -> None:
        """A task that could not start: a missing model file gets *Locate…*, the rest a warning."""
        if isinstance(exc, InputError):
            for entry in self.controller.project.models:
                if Path(exc.path) == Path(entry.mesh_path):
                    self.offer_locate(entry.component, exc)
                    return
        self.notices.warn(title, str(exc).strip("'\""))
