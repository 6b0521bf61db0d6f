"""The File menu and the session life cycle of the main window: open, save, the demo,
import, recent files, calibration, autosave and crash recovery, and dropped files.

An open project file is locked (``fluorogui.io.project.lock``) so that the command line or a
second app cannot write it at the same time. A file another live program holds is not
opened behind its back: a dialog says who holds it and offers to open it read-only
(look, and save a copy with Save As).

``SessionFiles`` is given what it works with: the session controller, the task runner,
the settings, the ``Notices`` it speaks to the user through, and two callables of the
window (close it; refresh its title). Its actions are declared in ``gui.layout.actions``."""
from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QObject, QSettings, QStandardPaths, Qt
from PySide6.QtWidgets import QApplication, QFileDialog, QMenu, QMessageBox

from fluorogui.gui.notices import Notices
from fluorogui.gui.worker import TaskRunner
from fluorogui.io.errors import InputError, collected_input_warnings
from fluorogui.io.meshes.read import MESH_SUFFIXES
from fluorogui.io.project.lock import ProjectLocked
from fluorogui.logs import data_dir, log_exception
from fluorogui.workflow.session.recovery import RecoveryJournal

PROJECT_FILTER = "fluorogui projects (*.fluoro);;All files (*)"
MAX_RECENT = 8


def app_data_dir() -> Path:
    """Where recovery files and the generated demo live: the operating system's place for
    the app's data (``fluorogui.logs.data_dir``; FLUOROGUI_DATA_DIR overrides)."""
    base = data_dir()
    base.mkdir(parents=True, exist_ok=True)
    return base


class SessionFiles(QObject):
    """The File menu's work and the session's life cycle."""

    def __init__(self, controller, runner: TaskRunner, settings: QSettings, notices: Notices, *,
                 close: Callable[[], object], refresh_title: Callable[[], None]) -> None:
        super().__init__(notices.parent_widget)
        self.controller = controller
        self.runner = runner
        self.settings = settings
        self.notices = notices
        self._close = close
        self._refresh_title = refresh_title
        self.recent_menu = QMenu("Open &recent", notices.parent_widget)
        # every change of the session's history (an edit, a tracked frame, a find) is kept in
        # the recovery file's journal as it happens: a crash loses at most the change in flight
        self.recovery = RecoveryJournal(self.controller.session, self.recovery_path,
                                        origin=lambda: str(self.controller.path or ""),
                                        failed=self._recovery_failed)
        self.refresh_recent()

    def quit(self) -> None:
        """Close the window (it asks about unsaved changes first)."""
        self._close()

    def calibrate_fluoroscope(self) -> None:
        """The calibration wizard (distortion from plates, geometry from a bead phantom)."""
        from fluorogui.gui.dialogs.calibration_wizard import CalibrationWizard

        wizard = CalibrationWizard(self.notices.parent_widget)
        if wizard.exec():
            self.notices.status("Wrote " + ", ".join(str(p) for p in wizard.written), 10000)

    def recent_files(self) -> list[str]:
        value = self.settings.value("recent", [])
        if isinstance(value, str):
            value = [value]
        return [v for v in (value or []) if v]

    def _add_recent(self, path: Path) -> None:
        items = [str(path)] + [p for p in self.recent_files() if p != str(path)]
        self.settings.setValue("recent", items[:MAX_RECENT])
        self.refresh_recent()

    def refresh_recent(self) -> None:
        self.recent_menu.clear()
        for p in self.recent_files():
            action = self.recent_menu.addAction(Path(p).name)
            action.setToolTip(p)
            action.triggered.connect(lambda _=False, path=p: self.open_project(path))
        self.recent_menu.setEnabled(bool(self.recent_files()))

    def maybe_save(self) -> bool:
        """Ask about unsaved changes; False if the user cancelled."""
        if not self.controller.dirty:
            return True
        answer = QMessageBox.question(
            self.notices.parent_widget, "Unsaved changes", "The session has unsaved changes. Save them first?",
            QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Discard | QMessageBox.StandardButton.Cancel,
            QMessageBox.StandardButton.Save)
        if answer == QMessageBox.StandardButton.Save:
            return self.save()
        return answer == QMessageBox.StandardButton.Discard

    def open_project(self, path=None, ask: bool = True, quiet_read_only: bool = False) -> bool:
        """Open a project file (asks for one when ``path`` is None). A failure shows a
        dialog naming the file and leaves the open project as it was; a file another
        program holds opens read-only if the user says so (without asking when
        ``quiet_read_only``)."""
        if self.runner.is_running():
            self.notices.status("Wait for the running task to end (or cancel it) first", 5000)
            return False
        if ask and not self.maybe_save():
            return False
        if path is None:
            name, _ = QFileDialog.getOpenFileName(self.notices.parent_widget, "Open project", str(self._last_dir()),
                                                  PROJECT_FILTER)
            if not name:
                return False
            path = name
        read_only = False
        with collected_input_warnings() as notes:  # read, but not as it stood: said after opening
            try:
                try:
                    self.controller.open(path)
                except ProjectLocked as exc:
                    if not quiet_read_only and not self._ask_read_only(exc):
                        return False
                    read_only = True
                    self.controller.open(path, read_only=True)
            except InputError as exc:
                self.notices.warn("Cannot open project", str(exc))
                return False
            except Exception as exc:  # noqa: BLE001 - a check the loader lacks: one dialog, traceback logged
                logged = log_exception(f"opening {path}")
                self.notices.warn("Cannot open project", f"{path}: could not be opened ({type(exc).__name__})"
                                  + (f"; details in {logged}" if logged else ""))
                return False
        self._add_recent(Path(path).resolve())
        self.settings.setValue("last_dir", str(Path(path).resolve().parent))
        self.notices.status(f"Opened {path}" + (" read-only" if read_only else ""), 5000)
        self.tell_input_notes("Opened with notes", notes)
        return True

    def tell_input_notes(self, title: str, notes: list[str]) -> None:
        """The inputs just read that were repaired or accepted with a note (``InputWarning``),
        in one dialog; nothing when there were none."""
        if notes:
            self.notices.warn(title, "Read, with these notes:\n" + "\n".join(notes))

    def _ask_read_only(self, exc: ProjectLocked) -> bool:
        """Tell the user who holds a project; True if they want it read-only anyway."""
        self.notices.last_error = str(exc)
        answer = QMessageBox.question(
            self.notices.parent_widget, "Project in use",
            f"{exc}.\n\nOpen it read-only? You can look at it and save a copy with Save As, but not save over "
            "the file while the other program has it.",
            QMessageBox.StandardButton.Open | QMessageBox.StandardButton.Cancel, QMessageBox.StandardButton.Cancel)
        if answer != QMessageBox.StandardButton.Open:
            self.notices.status(f"Not opened: {exc}", 10000)
            return False
        return True

    def _last_dir(self) -> Path:
        """The folder of the last project opened, unless that is the app's data folder
        (the demo's): file dialogs never start there."""
        last = Path(self.settings.value("last_dir", str(Path.home())))
        data = app_data_dir().resolve()
        if last.resolve() == data or data in last.resolve().parents:
            return Path.home()
        return last

    def open_demo(self, ask: bool = True) -> bool:
        """Open the built-in demo session (generated on first use)."""
        from fluorogui.simulation.demo import demo_project_path

        if ask and not self.maybe_save():
            return False
        QApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        self.notices.status("Preparing the demo session…")
        QApplication.processEvents()
        try:
            path = demo_project_path(app_data_dir() / "demo")
        except (InputError, OSError) as exc:
            QApplication.restoreOverrideCursor()
            self.notices.warn("Cannot build the demo", str(exc))
            return False
        QApplication.restoreOverrideCursor()
        opened = self.open_project(path, ask=False, quiet_read_only=True)  # another window may show it
        if opened:
            self.controller.project.settings["demo"] = True
            self._refresh_title()
            self.notices.status(
                "Demo session: press F5 to match the femoral component, then Ctrl+Return to accept", 15000)
        return opened

    def save(self) -> bool:
        c = self.controller
        if c.path is None or c.project.settings.get("demo") or c.read_only:
            return self.save_as()
        return self.save_to(self.controller.path)

    def default_save_dir(self) -> Path:
        """Where save dialogs start: the session file's folder, else the folder holding the
        session's images, else the last folder used, else Documents; never the app's data
        folder (where the demo and the autosave live)."""
        data = app_data_dir().resolve()

        def usable(folder) -> bool:
            folder = Path(folder).resolve()
            return folder.is_dir() and folder != data and data not in folder.parents

        c = self.controller
        candidates = [c.path.parent] if c.path is not None else []
        folders = []
        for frame in c.frames[:1]:
            folders = [p.parent for p in c.session.image_paths(frame) if p is not None]
        if folders:
            candidates.append(Path(os.path.commonpath([str(f.resolve()) for f in folders])))
        candidates.append(self._last_dir())
        for folder in candidates:
            if usable(folder):
                return Path(folder)
        documents = QStandardPaths.writableLocation(QStandardPaths.StandardLocation.DocumentsLocation)
        return Path(documents) if documents and Path(documents).is_dir() else Path.home()

    def save_as(self) -> bool:
        c = self.controller
        name = c.path.name if c.path is not None and not c.project.settings.get("demo") else "session.fluoro"
        start = str(self.default_save_dir() / name)
        name, _ = QFileDialog.getSaveFileName(self.notices.parent_widget, "Save project as", start, PROJECT_FILTER)
        if not name:
            return False
        if not name.endswith(".fluoro"):
            name += ".fluoro"
        self.controller.project.settings.pop("demo", None)
        return self.save_to(Path(name))

    def save_to(self, path: Path) -> bool:
        try:
            self.controller.save(path)
        except (InputError, OSError) as exc:
            self.notices.warn("Cannot save project", str(exc))
            return False
        self._add_recent(path.resolve())
        self.recovery.discard()
        self._refresh_title()
        self.notices.status(f"Saved {path}", 5000)
        return True

    def import_session(self, paths: dict | None = None, folder: Path | None = None) -> bool:
        """The import dialog (optionally pre-filled); the imported session replaces this one."""
        from fluorogui.gui.dialogs.import_dialog import ImportDialog

        if not self.maybe_save():
            return False
        dialog = ImportDialog(self.notices.parent_widget)
        if folder is not None:
            dialog.fill_from_folder(folder)
        if paths:
            dialog.fill(**paths)
        with collected_input_warnings() as notes:
            accepted = dialog.exec() == ImportDialog.DialogCode.Accepted and dialog.project is not None
        if not accepted:
            return False
        self.controller.set_project(dialog.project, None)
        self.controller.session.history.reset_clean()  # never saved: closing asks
        self.notices.status("Imported. Save the session to keep it (Ctrl+S)", 8000)
        self.tell_input_notes("Imported with notes", notes)
        return True

    # -- autosave and recovery -------------------------------------------------------------
    def recovery_path(self) -> Path:
        return app_data_dir() / "recovery" / "autosave.fluoro"

    def autosave(self) -> bool:
        """Write the whole session to the recovery file if it has unsaved changes (between
        such writes the recovery journal keeps every change)."""
        if not self.controller.dirty or not self.controller.project.views:
            return False
        try:
            self.recovery.write_whole()
        except (InputError, OSError) as exc:
            self._recovery_failed(exc)
            return False
        self.notices.status("Autosaved for recovery", 3000)
        return True

    def _recovery_failed(self, exc: Exception) -> None:
        self.notices.status(f"Autosave failed: {exc}", 10000)

    def offer_recovery(self) -> bool:
        """After a crash: offer the autosaved session. True if it was recovered."""
        path = self.recovery_path()
        if not path.exists():
            return False
        info = {}
        try:
            info = json.loads(path.with_suffix(".json").read_text())
        except (OSError, ValueError):
            pass
        origin = info.get("origin") or ""
        answer = QMessageBox.question(
            self.notices.parent_widget, "Recover session",
            "fluorogui did not close normally. Recover the autosaved session"
            + (f" of {Path(origin).name}" if origin else "") + "?",
            QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No, QMessageBox.StandardButton.Yes)
        if answer != QMessageBox.StandardButton.Yes:
            self.recovery.discard()
            return False
        try:
            self.controller.open(path, read_only=True)  # the recovery file is this app's own
        except InputError as exc:
            self.notices.warn("Cannot recover the session", str(exc))
            return False
        held = self.controller.claim(origin) if origin else ""
        if not origin:
            self.controller.session.path = None
            self.controller.read_only = False
        self.controller.session.history.reset_clean()
        self._refresh_title()
        self.notices.status("Recovered; save to keep it" + (
            f" (read-only: {held}; save a copy with Save As)" if held else ""), 8000)
        return True

    # -- dropped files ---------------------------------------------------------------------
    def open_paths(self, paths: list[Path]) -> None:
        """A dropped project opens; dropped folders, images, meshes or calibrations fill
        the import dialog."""
        projects = [p for p in paths if p.suffix == ".fluoro"]
        if projects:
            self.open_project(projects[0])
            return
        fill: dict = {}
        meshes = [p for p in paths if p.suffix.lower() in MESH_SUFFIXES]
        for m in meshes:
            fill.setdefault("tibial" if "tib" in m.name.lower() else "femoral", m)
        folders = [p for p in paths if p.is_dir()]
        for k, folder in enumerate(folders[:2] if len(folders) > 1 else []):
            fill[f"images{k + 1}"] = folder
        calibrations = [p for p in paths if p.suffix.lower() in {".txt", ".json", ".cal"}]
        for k, cal in enumerate(calibrations[:2]):
            fill[f"calibration{k + 1}"] = cal
        self.import_session(fill, folder=folders[0] if len(folders) == 1 else None)
