"""The Kinematics panel's presenter: the panel's rows kept in step with the session (the
frame on screen, the side, the poses as they change), its figure saved, the side and the
anatomical frames set. The rows come from ``Session.knee_rows`` and the figure from
``fluorogui.workflow.exports``; this only asks the user and shows the result.

The contact rows (``workflow.contact``, ~8 ms a frame) are computed off the GUI thread, in a
runner of their own (never blocking a match), when the contact plot is shown and the
poses changed; a change during the computation starts another once it ends. With *View →
Condyle contact points* the 3D scene shows the current frame's points on the tray (placed
by the tray's pose as it is now, so they follow it at once)."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtWidgets import QDialog, QFileDialog

from fluorogui.core.knee.kinematics import KinematicsError
from fluorogui.gui.dialogs.anatomical_frame import AnatomicalFrameDialog
from fluorogui.gui.notices import Notices
from fluorogui.gui.panels.knee_panel import KneePanel
from fluorogui.gui.worker import TaskRunner
from fluorogui.io.errors import InputError
from fluorogui.workflow import exports
from fluorogui.workflow.contact import contact_world_points, session_contact_job


class KinematicsPresenter(QObject):
    """The Kinematics panel (a ``KneePanel``) of a main window."""

    contact_changed = Signal()  # new contact rows (``contact_rows``)

    def __init__(self, controller, panel: KneePanel, notices: Notices, *,
                 export_folder: Callable[[], Path], scene=None, points_action=None) -> None:
        """``export_folder``: where a saved figure goes by default (the export folder);
        ``scene``: the 3D scene widget (None without one); ``points_action``: the checkable
        *Condyle contact points* action."""
        super().__init__(notices.parent_widget)
        self.controller = c = controller
        self.panel = panel
        self.notices = notices
        self._export_folder = export_folder
        self.scene = scene
        self.points_action = points_action
        panel.frame_selected.connect(c.set_frame)
        panel.side_chosen.connect(lambda side: c.session.set_side(side))
        panel.export_figure_requested.connect(self.export_figure)
        panel.edit_frames_requested.connect(self.edit_anatomical_frames)
        panel.plot_changed.connect(lambda _plot: self.refresh_contact())
        self.contact_rows: list = []  # of the poses when last computed
        self.contact_stale = True
        self.contact_wanted = False  # by the 3D scene's condyle points, besides the plot
        self._poses_seen = 0  # counts refreshes: a result of older poses is dropped
        self.contact_runner = TaskRunner(self)
        self.contact_runner.finished.connect(self._contact_done)
        self.contact_runner.failed.connect(self._contact_failed)
        # poses change in bursts (a tracked frame stores two; an import hundreds): recompute
        # once the burst is over, off the path of the frame the user is looking at
        self.refresh_timer = QTimer(self)
        self.refresh_timer.setSingleShot(True)
        self.refresh_timer.setInterval(250)
        self.refresh_timer.timeout.connect(self.refresh_knee)
        c.project_replaced.connect(self.refresh_knee)
        c.pose_changed.connect(lambda _f, _c: self.refresh_timer.start())
        c.knee_changed.connect(lambda _what: self.refresh_knee())
        c.model_changed.connect(lambda _component: self.refresh_knee())  # its default anatomical frame too
        c.frame_changed.connect(lambda frame: panel.set_current(frame))
        c.frame_changed.connect(lambda _frame: self.show_contact_points())
        c.pose_changed.connect(lambda _f, component: component == "tibial" and self.show_contact_points())
        self.contact_changed.connect(self.show_contact_points)

    @property
    def session(self):
        return self.controller.session

    def refresh_knee(self) -> None:
        """Recompute the rows from the session (cheap) and hand them to the panel."""
        session = self.session
        self.contact_stale = True
        self._poses_seen += 1
        if not session.frames:
            self.panel.set_rows([], None)
            self._no_contact("No frames.")
            return
        try:
            rows = session.knee_rows()
        except (InputError, KinematicsError, KeyError) as exc:
            self.panel.set_rows([], None)
            self.panel.status.setText(f"No kinematics: {exc}")
            self._no_contact(f"No contact: {exc}")
            return
        self.panel.set_side(session.side)
        self.panel.set_rows(rows, self.controller.frame)
        self.refresh_contact()

    # -- contact ----------------------------------------------------------------------------------
    def refresh_contact(self) -> None:
        """Start computing the contact rows if they are out of date and shown (or
        ``contact_wanted``: the 3D scene's condyle points)."""
        if not self.contact_stale or not (self.contact_wanted or self.panel.shows_contact()) or not self.panel.rows:
            return
        if self.contact_runner.is_running():
            return  # _contact_done starts the next
        try:
            job = session_contact_job(self.session, knee_rows=self.panel.rows)
        except (InputError, KinematicsError, KeyError) as exc:
            self._no_contact(f"No contact: {exc}")
            return
        self.contact_stale = False
        if not self.panel.contact_rows:
            self.panel.set_contact([], None, "Computing the contact…")
        seen = self._poses_seen
        self.contact_runner.start(lambda _reporter: (seen, *job()), "contact")

    def _contact_done(self, result) -> None:
        seen, rows, pivot = result
        if seen == self._poses_seen:
            self.contact_rows = rows
            self.panel.set_contact(rows, pivot)
            self.contact_changed.emit()
        self.refresh_contact()

    def _contact_failed(self, message: str) -> None:
        self._no_contact(f"No contact: {message}")
        self.refresh_contact()

    def _no_contact(self, note: str) -> None:
        self.contact_rows = []
        self.panel.set_contact([], None, note)
        self.contact_changed.emit()

    def toggle_contact_points(self, on: bool | None = None) -> None:
        """Show or hide the condyles' points in the 3D scene (by default as the action says)."""
        if on is None:
            on = self.points_action.isChecked() if self.points_action is not None else not self.contact_wanted
        if self.points_action is not None:
            self.points_action.setChecked(on)
        self.contact_wanted = bool(on)
        self.refresh_contact()
        self.show_contact_points()

    def show_contact_points(self) -> None:
        """The current frame's points in the scene, from the last contact rows and the
        tray's pose now; hidden when off, missing or not computed yet."""
        if self.scene is None:
            return
        points = None
        frame = self.controller.frame
        row = next((r for r in self.contact_rows if r.frame == frame), None) if self.contact_wanted else None
        record = self.session.pose_record("tibial", frame) if row is not None else None
        if record is not None and row.status != "missing":
            try:
                points = contact_world_points(row, record.pose, self.session.anatomical_frame("tibial"),
                                              self.session.side or "right")
            except (InputError, KinematicsError, KeyError):
                points = None
        self.scene.scene.set_contact_points(points)

    def close(self) -> None:
        """Wait for a contact computation (the window is closing)."""
        self.contact_runner.wait()

    def export_figure(self) -> None:
        if not self.session.frames:
            return
        stem = self.session.path.stem if self.session.path else "kinematics"
        path, _ = QFileDialog.getSaveFileName(self.notices.parent_widget, "Save the kinematics figure",
                                              str(self._export_folder() / f"{stem}_kinematics.png"),
                                              "PNG (*.png);;SVG (*.svg);;PDF (*.pdf)")
        if not path:
            return
        try:
            exports.export_plot(self.session, path, self.panel.against.currentData())
        except (InputError, ValueError) as exc:
            self.notices.warn("Save figure failed", str(exc))
            return
        self.notices.status(f"Saved {path}", 6000)

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
            self.notices.warn("Anatomical frame", str(exc))
            return
        dialog = AnatomicalFrameDialog(component, current, default, session.anatomical_frame_source(component),
                                       self.notices.parent_widget)
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return
        if dialog.reset_requested and (abs(dialog.result_matrix - default).max() < 1e-8):
            session.reset_anatomical_frame(component)
        else:
            session.set_anatomical_frame(component, dialog.result_matrix)
