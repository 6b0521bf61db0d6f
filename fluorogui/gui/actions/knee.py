"""*File → Export…* and *File → Import poses…* of the main window (their actions are
declared in ``gui.layout.actions``; the Kinematics panel's presenter is ``actions.kinematics``).
Everything computed or written comes from ``fluorogui.workflow`` (``knee``, ``exports``);
this only asks the user and shows the result. ``KneeActions`` still works through the
window (its ``warn``, ``ask``, status bar, settings and ``files``)."""
from __future__ import annotations

import os
from pathlib import Path

from PySide6.QtCore import QObject, QStandardPaths
from PySide6.QtWidgets import QDialog, QFileDialog, QInputDialog

from fluorogui.core.knee.kinematics import KinematicsError
from fluorogui.gui.actions.files import app_data_dir
from fluorogui.gui.actions.tasks import frame_list
from fluorogui.gui.dialogs.export_dialog import ExportDialog
from fluorogui.io.errors import InputError, collected_input_warnings
from fluorogui.workflow import exports
from fluorogui.workflow.exports import ExportOptions

IMPORT_FILTER = "Poses (*.csv *.tra *.jts);;All files (*)"


class KneeActions(QObject):
    """Export and import of poses of a main window."""

    def __init__(self, window) -> None:
        super().__init__(window)
        self.window = window
        self.controller = window.controller
        self.last_export: list = []

    @property
    def session(self):
        return self.controller.session

    def _export_folder(self) -> Path:
        """Where exports go by default: the project's folder; for an unsaved project (or one
        in a folder we cannot write, or the demo in the app's data folder) the last folder
        exported to, else Documents. Never the images' folder: that is often read-only on a
        lab server."""
        data = app_data_dir().resolve()

        def writable(folder) -> bool:
            if not folder:
                return False
            folder = Path(folder).resolve()
            return (folder.is_dir() and os.access(folder, os.W_OK | os.X_OK) and folder != data
                    and data not in folder.parents)

        path = self.session.path
        last = self.window.settings.value("export_dir", "")
        documents = QStandardPaths.writableLocation(QStandardPaths.StandardLocation.DocumentsLocation)
        for folder in (path.parent if path is not None else None, last, documents, Path.home()):
            if writable(folder):
                return Path(folder)
        return Path.home()

    def export_results(self) -> None:
        session = self.session
        if not session.frames:
            self.window.warn("Export", "Open or import a session first.")
            return
        stem = session.path.stem if session.path else "fluorogui"
        dialog = ExportDialog(self._export_folder(), stem, session.n_views, self.window,
                              fps=exports.frame_rate(session))
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return
        targets = dialog.targets()
        options = ExportOptions(include_unreviewed=dialog.include_unreviewed.isChecked(),
                                view=dialog.view.currentData())
        fps = dialog.fps()
        timed = [f.name for f in exports.formats() if f.timed and f.name in targets]
        if timed and fps is None:
            self.window.warn("Export", f"{', '.join(targets[k].name for k in timed)}: the frame rate is needed "
                                       "(time = frame number / frame rate); give the images' frame rate.")
            return
        if fps is not None and fps != exports.frame_rate(session):
            exports.set_frame_rate(session, fps)  # the dialog's frame rate is the project's (undoable)
        try:
            written = exports.write_exports(session, targets, options)
        except (InputError, KinematicsError, KeyError, ValueError) as exc:
            self.window.warn("Export failed", str(exc))
            return
        notes = exports.export_notes(session, list(targets), options, naming=lambda f: f.short,
                                     remedy="accept a pose, Ctrl+Return, to include it")
        left_out = "".join(f"; {_counted(poses)}{words}" for poses, words in notes)
        self.window.statusBar().showMessage(f"Exported {len(written)} file{'s' if len(written) != 1 else ''} "
                                            f"to {Path(dialog.folder.text())}{left_out}", 8000)
        self.window.settings.setValue("export_dir", dialog.folder.text())
        self.last_export = written

    def import_poses_file(self, path: str | None = None, component: str | None = None,
                          view: int | None = None) -> int:
        session = self.session
        if not session.frames:
            self.window.warn("Import poses", "Open or import a session first.")
            return 0
        if path is None:
            path, _ = QFileDialog.getOpenFileName(self.window, "Import poses", str(self._export_folder()),
                                                  IMPORT_FILTER)
            if not path:
                return 0
        if Path(path).suffix.lower() == ".jts":
            if component is None:
                component, ok = QInputDialog.getItem(self.window, "Import JointTrack poses",
                                                     "Component in this file:", ["femoral", "tibial"], 0, False)
                if not ok:
                    return 0
            if view is None:
                names = [f"View {k + 1}" for k in range(session.n_views)]
                choice, ok = QInputDialog.getItem(self.window, "Import JointTrack poses", "Camera frame of view:",
                                                  names, 0, False)
                if not ok:
                    return 0
                view = names.index(choice)
        kept: list = []
        try:
            with collected_input_warnings() as notes:
                count = exports.import_poses(session, path, component=component, view=view or 0, kept=kept)
                if kept and self.window.ask(
                        "Import poses", f"{len(kept)} pose{'s' if len(kept) > 1 else ''} in {Path(path).name} "
                        f"would replace matched or accepted ones (frame {frame_list(f for f, _ in kept)}). "
                        "Replace them too?"):
                    count = exports.import_poses(session, path, component=component, view=view or 0, replace=True)
                    kept = []
        except (InputError, KinematicsError, ValueError) as exc:
            self.window.warn("Import poses failed", str(exc))
            return 0
        self.window.statusBar().showMessage(
            f"Imported {count} poses from {Path(path).name}; they are marked 'placed' until reviewed or matched"
            + (f"; kept {len(kept)} matched or accepted" if kept else ""), 8000)
        self.window.files.tell_input_notes("Imported poses with notes", notes)
        return count


def _counted(poses: list) -> str:
    """"3 poses " for a note about poses ("" for a note about the file)."""
    return f"{len(poses)} pose{'s' if len(poses) != 1 else ''} " if poses else ""
