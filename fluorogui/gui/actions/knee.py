"""The knee actions of the main window: the Kinematics panel kept in step with the session,
*File → Export…* and *File → Import poses…*, the side and the anatomical frames.
Everything computed or written comes from ``fluorogui.workflow`` (``knee``, ``exports``);
this only asks the user and shows the result."""
from __future__ import annotations

import os
from pathlib import Path

from PySide6.QtCore import QObject, QStandardPaths, QTimer
from PySide6.QtWidgets import QDialog, QFileDialog, QInputDialog

from fluorogui.core.knee.kinematics import KinematicsError
from fluorogui.gui.actions.files import app_data_dir
from fluorogui.gui.actions.tasks import frame_list
from fluorogui.gui.dialogs.anatomical_frame import AnatomicalFrameDialog
from fluorogui.gui.dialogs.export_dialog import TIMED_KINDS, ExportDialog
from fluorogui.io.errors import InputError, collected_input_warnings
from fluorogui.workflow import exports

IMPORT_FILTER = "Poses (*.csv *.tra *.jts);;All files (*)"


class KneeActions(QObject):
    """Export, import of poses and the Kinematics panel (``window.knee_panel``) of a main window."""

    def __init__(self, window) -> None:
        super().__init__(window)
        self.window = window
        self.controller = c = window.controller
        self.panel = panel = window.knee_panel
        self.last_export: list = []
        self.export_action = window.add_action(
            "&Export results…", self.export_results, "Ctrl+Shift+E",
            tip="Write poses, kinematics, Autoscoper .tra, JointTrack .jts or the figure")
        self.import_poses_action = window.add_action(
            "&Import poses…", lambda: self.import_poses_file(),
            tip="Read poses from our CSV, Autoscoper .tra or JointTrack .jts")
        panel.frame_selected.connect(c.set_frame)
        panel.side_chosen.connect(lambda side: c.session.set_side(side))
        panel.export_figure_requested.connect(self.export_figure)
        panel.edit_frames_requested.connect(self.edit_anatomical_frames)
        # poses change in bursts (a tracked frame stores two; an import hundreds): recompute
        # once the burst is over, off the path of the frame the user is looking at
        self.refresh_timer = QTimer(self)
        self.refresh_timer.setSingleShot(True)
        self.refresh_timer.setInterval(250)
        self.refresh_timer.timeout.connect(self.refresh_knee)
        c.project_replaced.connect(self.refresh_knee)
        c.pose_changed.connect(lambda _f, _c: self.refresh_timer.start())
        c.knee_changed.connect(lambda _what: self.refresh_knee())
        c.frame_changed.connect(lambda frame: panel.set_current(frame))

    @property
    def session(self):
        return self.controller.session

    def refresh_knee(self) -> None:
        """Recompute the rows from the session (cheap) and hand them to the panel."""
        session = self.session
        if not session.frames:
            self.panel.set_rows([], None)
            return
        try:
            rows = session.knee_rows()
        except (InputError, KinematicsError, KeyError) as exc:
            self.panel.set_rows([], None)
            self.panel.status.setText(f"No kinematics: {exc}")
            return
        self.panel.set_side(session.side)
        self.panel.set_rows(rows, self.controller.frame)

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
        fps, unreviewed = dialog.fps(), dialog.include_unreviewed.isChecked()
        timed = [k for k in TIMED_KINDS if k in targets]
        if timed and fps is None:
            self.window.warn("Export", f"{', '.join(targets[k].name for k in timed)}: the frame rate is needed "
                                       "(time = frame number / frame rate); give the images' frame rate.")
            return
        if fps is not None and fps != exports.frame_rate(session):
            exports.set_frame_rate(session, fps)  # the dialog's frame rate is the project's (undoable)
        try:
            rows = session.knee_rows()  # once, for every file written
        except (InputError, KinematicsError, KeyError) as exc:
            self.window.warn("Export failed", str(exc))
            return
        writers = {
            "poses": lambda p: [exports.export_poses_csv(session, p, rows)],
            "kinematics": lambda p: [exports.export_kinematics_csv(session, p, rows)],
            "tra": lambda p: [exports.export_tra(session, p, unreviewed)],
            "jts": lambda p: exports.export_jts(session, p, dialog.view.currentData(), unreviewed),
            "plot": lambda p: [exports.export_plot(session, p, rows=rows)],
            "c3d": lambda p: [exports.export_c3d(session, p, include_unreviewed=unreviewed)],
            "trc": lambda p: [exports.export_trc(session, p, include_unreviewed=unreviewed)],
            "mot": lambda p: [exports.export_mot(session, p, rows, include_unreviewed=unreviewed)],
            "xromm": lambda p: [exports.export_xromm(session, p, unreviewed)],
        }
        written = []
        try:
            for key, path in targets.items():
                written += writers[key](path)
        except (InputError, KinematicsError, ValueError) as exc:
            self.window.warn("Export failed", str(exc))
            return
        flagged = exports.unreviewed_matches(session) if {"tra", "jts"} & set(targets) and not unreviewed else []
        left_out = (f"; {len(flagged)} pose{'s' if len(flagged) != 1 else ''} flagged for review left out of "
                    ".tra/.jts (accept a pose, Ctrl+Return, to include it)") if flagged else ""
        motion = {"c3d", "trc", "mot", "xromm"} & set(targets)
        unmatched = exports.left_out_of_motion_files(session) if motion and not unreviewed else []
        if unmatched:
            left_out += (f"; {len(unmatched)} pose{'s' if len(unmatched) != 1 else ''} not matched or accepted left "
                         "out of the C3D/OpenSim/XMALab files")
        if "c3d" in targets and not exports.consecutive_frames(session):
            left_out += ("; the frame numbers are not consecutive, so a C3D reader's times are not frame / fps "
                         "(the C3D keeps the true ones in FLUOROGUI:FRAMES and :TIMES)")
        self.window.statusBar().showMessage(f"Exported {len(written)} file{'s' if len(written) != 1 else ''} "
                                            f"to {Path(dialog.folder.text())}{left_out}", 8000)
        self.window.settings.setValue("export_dir", dialog.folder.text())
        self.last_export = written

    def export_figure(self) -> None:
        if not self.session.frames:
            return
        stem = self.session.path.stem if self.session.path else "kinematics"
        path, _ = QFileDialog.getSaveFileName(self.window, "Save the kinematics figure",
                                              str(self._export_folder() / f"{stem}_kinematics.png"),
                                              "PNG (*.png);;SVG (*.svg);;PDF (*.pdf)")
        if not path:
            return
        try:
            exports.export_plot(self.session, path, self.panel.against.currentData())
        except (InputError, ValueError) as exc:
            self.window.warn("Save figure failed", str(exc))
            return
        self.window.statusBar().showMessage(f"Saved {path}", 6000)

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
                count = exports.import_poses(session, path, component, view or 0, kept=kept)
                if kept and self.window.ask(
                        "Import poses", f"{len(kept)} pose{'s' if len(kept) > 1 else ''} in {Path(path).name} "
                        f"would replace matched or accepted ones (frame {frame_list(f for f, _ in kept)}). "
                        "Replace them too?"):
                    count = exports.import_poses(session, path, component, view or 0, replace=True)
                    kept = []
        except (InputError, KinematicsError, ValueError) as exc:
            self.window.warn("Import poses failed", str(exc))
            return 0
        self.window.statusBar().showMessage(
            f"Imported {count} poses from {Path(path).name}; they are marked 'placed' until reviewed or matched"
            + (f"; kept {len(kept)} matched or accepted" if kept else ""), 8000)
        self.window.files.tell_input_notes("Imported poses with notes", notes)
        return count

    def edit_anatomical_frames(self, component: str | None = None) -> None:
        session = self.session
        names = [c for c in ("femoral", "tibial") if session.project.model(c) is not None]
        if not names:
            return
        if component is None:
            component = self.controller.component if self.controller.component in names else names[0]
        try:
            current = session.anatomical_frame(component)
            default = session.default_anatomical_frame(component)
        except (InputError, KinematicsError, KeyError) as exc:
            self.window.warn("Anatomical frame", str(exc))
            return
        dialog = AnatomicalFrameDialog(component, current, default, session.anatomical_frame_source(component),
                                       self.window)
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return
        if dialog.reset_requested and (abs(dialog.result_matrix - default).max() < 1e-8):
            session.reset_anatomical_frame(component)
        else:
            session.set_anatomical_frame(component, dialog.result_matrix)
