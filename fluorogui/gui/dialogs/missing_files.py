"""A component whose mesh file is missing or unreadable: its stale 3D model and overlays
are cleared (never the previous project's), and a dialog offers *Locate…* to point the
session at the file where it is now (``Session.relink_mesh``, one undoable step).

``MissingFiles`` is a mixin of ``MainWindow``.
"""
from __future__ import annotations

from pathlib import Path

from PySide6.QtGui import QColor
from PySide6.QtWidgets import QFileDialog, QMessageBox

from fluorogui.io.errors import InputError
from fluorogui.io.meshes.read import MESH_SUFFIXES

MESH_FILTER = f"Surface models ({' '.join('*' + s for s in sorted(MESH_SUFFIXES))});;All files (*)"


class MissingFiles:
    """Loading the components' models into the 3D scene, and relinking missing ones."""

    def _load_scene_model(self, name: str) -> InputError | None:
        """Put a component's mesh in the 3D scene; on failure remove what was there and
        return the error."""
        s = self.controller.session
        try:
            vertices, faces = s.raw_mesh(name)
        except (InputError, KeyError) as exc:
            if self.scene_widget is not None:
                self.scene_widget.scene.remove_model(name)
            for panel in self.panels:
                panel.set_model_outline(name, None)
            return exc if isinstance(exc, InputError) else InputError(name, "no model in this session")
        if self.scene_widget is not None:
            from fluorogui.gui.session_view import COMPONENT_COLOURS

            colour = COMPONENT_COLOURS.get(name, QColor(200, 200, 200)).getRgbF()[:3]
            self.scene_widget.scene.set_model(name, vertices, faces, colour)
        return None

    def offer_locate(self, name: str, error: InputError) -> bool:
        """Say a component's model cannot be loaded and offer *Locate…*; True if relinked."""
        self.last_error = str(error)
        self.statusBar().showMessage(str(error), 10000)
        box = QMessageBox(QMessageBox.Icon.Warning, "Model file not found",
                          f"The {name} model cannot be loaded:\n{error}\n\nLocate the file where it is now?",
                          QMessageBox.StandardButton.Cancel, self)
        locate = box.addButton("Locate…", QMessageBox.ButtonRole.AcceptRole)
        box.setDefaultButton(locate)
        if self._ask(box) is not locate:
            return False
        start = str(Path(error.path).parent if Path(error.path).parent.is_dir() else self.default_save_dir())
        path, _ = QFileDialog.getOpenFileName(self, f"Locate the {name} model", start, MESH_FILTER)
        return bool(path) and self.relink_model(name, path)

    def _ask(self, box: QMessageBox):
        """Show a dialog and return the button clicked (tests replace this)."""
        box.exec()
        return box.clickedButton()

    def relink_model(self, name: str, path) -> bool:
        try:
            self.controller.session.relink_mesh(name, path)
        except InputError as exc:
            self._warn("Cannot use this model", str(exc))
            return False
        self.statusBar().showMessage(f"The {name} model is now {path}", 8000)
        return True

    def _job_error(self, title: str, exc: Exception) -> None:
        """A task that could not start: a missing model file gets *Locate…*, the rest a warning."""
        if isinstance(exc, InputError):
            for entry in self.controller.project.models:
                if Path(exc.path) == Path(entry.mesh_path):
                    self.offer_locate(entry.component, exc)
                    return
        self._warn(title, str(exc).strip("'\""))

    def _model_changed(self, name: str) -> None:
        """A component's mesh file changed (relinked, or undone): reload it everywhere."""
        if self._load_scene_model(name) is None and self.controller.frame is not None:
            self._show_pose(name)
            self._show_pose_status()
