"""What ``MainWindow`` does with the knee (a mixin): the Kinematics dock kept in step with
the session, *File → Export…* and *File → Import poses…*, the side and the anatomical
frames. Everything computed or written comes from ``fluorogui.workflow`` (``knee``,
``exports``); this only asks the user and shows the result."""
from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QInputDialog,
    QLineEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from fluorogui.core.knee.kinematics import KinematicsError
from fluorogui.gui.panels.knee_panel import AnatomicalFrameDialog, KneePanel
from fluorogui.io.errors import InputError
from fluorogui.workflow import exports

EXPORT_KINDS = (  # key, label, default file name
    ("poses", "Poses, residuals, status and kinematics (CSV)", "{stem}_poses.csv"),
    ("kinematics", "Kinematics (CSV)", "{stem}_kinematics.csv"),
    ("tra", "Autoscoper poses (.tra)", "{stem}.tra"),
    ("jts", "JointTrack poses (femoral.jts, tibial.jts)", "{stem}_jointtrack"),
    ("plot", "Kinematics figure (PNG)", "{stem}_kinematics.png"),
)
IMPORT_FILTER = "Poses (*.csv *.tra *.jts);;All files (*)"


class ExportDialog(QDialog):
    """Which results to write, where, and (for JointTrack) in which view's camera frame."""

    def __init__(self, folder: Path, stem: str, views: int, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Export results")
        self.checks: dict[str, QCheckBox] = {}
        self.names: dict[str, QLineEdit] = {}
        form = QFormLayout()
        self.folder = QLineEdit(str(folder))
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.folder, 1)
        row.addWidget(browse)
        form.addRow("Folder", row)
        for key, label, pattern in EXPORT_KINDS:
            check = QCheckBox(label)
            check.setChecked(key in ("poses", "kinematics"))
            name = QLineEdit(pattern.format(stem=stem))
            name.setObjectName(f"export_{key}")
            self.checks[key], self.names[key] = check, name
            form.addRow(check, name)
        self.view = QComboBox()
        for k in range(views):
            self.view.addItem(f"View {k + 1}", k)
        form.addRow("JointTrack camera", self.view)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        buttons.button(QDialogButtonBox.StandardButton.Ok).setText("Export")
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(buttons)

    def _browse(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Export to folder", self.folder.text())
        if folder:
            self.folder.setText(folder)

    def targets(self) -> dict[str, Path]:
        folder = Path(self.folder.text())
        return {k: folder / self.names[k].text() for k, check in self.checks.items() if check.isChecked()}


class KneeActions:
    """The knee part of ``MainWindow`` (a mixin; needs ``controller``, ``_dock``, ``_warn``)."""

    def _build_knee_dock(self, area) -> None:
        self.knee_panel = KneePanel()
        self.knee_dock = self._dock("Kinematics", self.knee_panel, area, "kneeDock")
        self.knee_panel.frame_selected.connect(self.controller.set_frame)
        self.knee_panel.side_chosen.connect(lambda side: self.session.set_side(side))
        self.knee_panel.export_figure_requested.connect(self.export_figure)
        self.knee_panel.edit_frames_requested.connect(self.edit_anatomical_frames)
        c = self.controller
        # poses change in bursts (a tracked frame stores two; an import hundreds): recompute
        # once the burst is over, off the path of the frame the user is looking at
        self._knee_timer = QTimer(self)
        self._knee_timer.setSingleShot(True)
        self._knee_timer.setInterval(250)
        self._knee_timer.timeout.connect(self.refresh_knee)
        c.project_replaced.connect(self.refresh_knee)
        c.pose_changed.connect(lambda _f, _c: self._knee_timer.start())
        c.knee_changed.connect(lambda _what: self.refresh_knee())
        c.frame_changed.connect(lambda frame: self.knee_panel.set_current(frame))

    def _knee_menu_actions(self, file_menu, before) -> None:
        self.export_action = self._action("&Export results…", self.export_results, "Ctrl+Shift+E",
                                          tip="Write poses, kinematics, Autoscoper .tra, JointTrack .jts or the figure")
        self.import_poses_action = self._action("&Import poses…", self.import_poses_file,
                                                tip="Read poses from our CSV, Autoscoper .tra or JointTrack .jts")
        file_menu.insertAction(before, self.export_action)
        file_menu.insertAction(before, self.import_poses_action)
        file_menu.insertSeparator(before)

    def refresh_knee(self) -> None:
        """Recompute the rows from the session (cheap) and hand them to the panel."""
        session = self.session
        if not session.frames:
            self.knee_panel.set_rows([], None)
            return
        try:
            rows = session.knee_rows()
        except (InputError, KinematicsError, KeyError) as exc:
            self.knee_panel.set_rows([], None)
            self.knee_panel.status.setText(f"No kinematics: {exc}")
            return
        self.knee_panel.set_side(session.side)
        self.knee_panel.set_rows(rows, self.controller.frame)

    def _export_folder(self) -> Path:
        """Beside the session file or its images, never in the app's data folder (the demo)."""
        return self.default_save_dir()

    def export_results(self) -> None:
        session = self.session
        if not session.frames:
            self._warn("Export", "Open or import a session first.")
            return
        stem = session.path.stem if session.path else "fluorogui"
        dialog = ExportDialog(self._export_folder(), stem, session.n_views, self)
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return
        targets = dialog.targets()
        try:
            rows = session.knee_rows()  # once, for every file written
        except (InputError, KinematicsError, KeyError) as exc:
            self._warn("Export failed", str(exc))
            return
        writers = {
            "poses": lambda p: [exports.export_poses_csv(session, p, rows)],
            "kinematics": lambda p: [exports.export_kinematics_csv(session, p, rows)],
            "tra": lambda p: [exports.export_tra(session, p)],
            "jts": lambda p: exports.export_jts(session, p, dialog.view.currentData()),
            "plot": lambda p: [exports.export_plot(session, p, rows=rows)],
        }
        written = []
        try:
            for key, path in targets.items():
                written += writers[key](path)
        except (InputError, KinematicsError, ValueError) as exc:
            self._warn("Export failed", str(exc))
            return
        flagged = exports.unreviewed_matches(session) if {"tra", "jts"} & set(targets) else []
        left_out = (f"; {len(flagged)} pose{'s' if len(flagged) != 1 else ''} flagged for review left out of "
                    ".tra/.jts (accept a pose, Ctrl+Return, to include it)") if flagged else ""
        self.statusBar().showMessage(f"Exported {len(written)} file{'s' if len(written) != 1 else ''} "
                                     f"to {Path(dialog.folder.text())}{left_out}", 8000)
        self.last_export = written

    def export_figure(self) -> None:
        if not self.session.frames:
            return
        stem = self.session.path.stem if self.session.path else "kinematics"
        path, _ = QFileDialog.getSaveFileName(self, "Save the kinematics figure",
                                              str(self._export_folder() / f"{stem}_kinematics.png"),
                                              "PNG (*.png);;SVG (*.svg);;PDF (*.pdf)")
        if not path:
            return
        try:
            exports.export_plot(self.session, path, self.knee_panel.against.currentData())
        except (InputError, ValueError) as exc:
            self._warn("Save figure failed", str(exc))
            return
        self.statusBar().showMessage(f"Saved {path}", 6000)

    def import_poses_file(self, path: str | None = None, component: str | None = None, view: int | None = None) -> int:
        session = self.session
        if not session.frames:
            self._warn("Import poses", "Open or import a session first.")
            return 0
        if path is None:
            path, _ = QFileDialog.getOpenFileName(self, "Import poses", str(self._export_folder()), IMPORT_FILTER)
            if not path:
                return 0
        if Path(path).suffix.lower() == ".jts":
            if component is None:
                component, ok = QInputDialog.getItem(self, "Import JointTrack poses", "Component in this file:",
                                                     ["femoral", "tibial"], 0, False)
                if not ok:
                    return 0
            if view is None:
                names = [f"View {k + 1}" for k in range(session.n_views)]
                choice, ok = QInputDialog.getItem(self, "Import JointTrack poses", "Camera frame of view:", names, 0, False)
                if not ok:
                    return 0
                view = names.index(choice)
        try:
            count = exports.import_poses(session, path, component, view or 0)
        except (InputError, KinematicsError, ValueError) as exc:
            self._warn("Import poses failed", str(exc))
            return 0
        self.statusBar().showMessage(f"Imported {count} poses from {Path(path).name}; they are marked "
                                     "'placed' until reviewed or matched", 8000)
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
            self._warn("Anatomical frame", str(exc))
            return
        dialog = AnatomicalFrameDialog(component, current, default, session.anatomical_frame_source(component), self)
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return
        if dialog.reset_requested and (abs(dialog.result_matrix - default).max() < 1e-8):
            session.reset_anatomical_frame(component)
        else:
            session.set_anatomical_frame(component, dialog.result_matrix)
