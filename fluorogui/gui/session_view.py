"""Showing the session in the main window: the frame on screen (images, outlines, model
overlays, 3D scene), the pose status of its components, the session tree and the
timeline, kept in step with the session's events.

``SessionView`` is a mixin of ``MainWindow``; it reads the session (``controller.session``)
and never changes it. Frames are frame numbers throughout.
"""
from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction, QColor
from PySide6.QtWidgets import QTreeWidgetItem

from fluorogui.core.matching.loop import predicted_outline
from fluorogui.core.outlines.spline import OutlineError
from fluorogui.gui import jobs
from fluorogui.gui.panels.matcher_panel import describe_pose
from fluorogui.io.errors import InputError
from fluorogui.workflow.session import FrameState

COMPONENT_COLOURS = {"femoral": QColor(90, 170, 255), "tibial": QColor(110, 220, 120)}


class SessionView:
    """What ``MainWindow`` shows of the session (a mixin)."""

    @property
    def session(self):
        return self.controller.session

    # -- a new project ---------------------------------------------------------------------------
    def _project_replaced(self) -> None:
        c, s = self.controller, self.controller.session
        self.place_clicks.clear()
        names = s.components()
        self.component_combo.blockSignals(True)
        self.component_combo.clear()
        self.component_combo.addItems(names)
        if c.component in names:
            self.component_combo.setCurrentText(c.component)
        self.component_combo.blockSignals(False)
        self.component_menu.clear()
        for action in self.component_actions.actions():
            self.component_actions.removeAction(action)
        for name in names:
            action = QAction(name, self, checkable=True)
            action.setChecked(name == c.component)
            action.triggered.connect(lambda _=False, n=name: c.set_component(n))
            self.component_actions.addAction(action)
            self.component_menu.addAction(action)
        for view, panel in enumerate(self.panels):
            # a single-plane session: one panel across the width (no session: both, with the hint)
            panel.setVisible(view < s.n_views or s.n_views == 0)
        missing = []
        if self.scene_widget is not None:
            scene = self.scene_widget.scene
            self.scene_widget.set_views(s.views)
            for name in scene.components:
                if name not in names:
                    scene.remove_model(name)  # the previous project's component
        for name in names:
            error = self._load_scene_model(name)
            if error is not None:
                missing.append((name, error))
        self.matcher.set_settings(s.settings.match)
        self.matcher.show_summary("")
        self._camera_pending = True
        self._refresh_tree()
        self._refresh_title()
        self.timeline.set_frames(s.frames, s.frame_states())
        for frame in s.frames:
            self.timeline.set_note(frame, self._frame_note(frame))
        self._component_changed(c.component)
        if missing:  # after the window shows the project: offer to relink each missing model
            from PySide6.QtCore import QTimer

            QTimer.singleShot(0, lambda: [self.offer_locate(name, error) for name, error in missing])

    def _refresh_tree(self) -> None:
        s = self.controller.session
        self.tree.clear()
        root = QTreeWidgetItem([s.path.name if s.path else "Untitled session"])
        views = QTreeWidgetItem(root, ["Views"])
        for i, v in enumerate(s.views):
            QTreeWidgetItem(views, [f"View {i + 1}: {v.name or 'calibrated'} ({v.image_size[0]}×{v.image_size[1]})"])
        models = QTreeWidgetItem(root, ["Components"])
        for name in s.components():
            item = QTreeWidgetItem(models, [f"{name}  ({s.project.model(name).mesh_path.name})"])
            item.setData(0, Qt.ItemDataRole.UserRole, ("component", name))
        frames = QTreeWidgetItem(root, [f"Frames ({len(s.frames)})"])
        for f in s.frames[:500]:
            item = QTreeWidgetItem(frames, [f"Frame {f}"])
            item.setData(0, Qt.ItemDataRole.UserRole, ("frame", f))
        self.tree.addTopLevelItem(root)
        root.setExpanded(True)
        views.setExpanded(True)
        models.setExpanded(True)

    def _tree_activated(self, item, _column=0) -> None:
        data = item.data(0, Qt.ItemDataRole.UserRole)
        if not data:
            return
        kind, value = data
        if kind == "component":
            self.controller.set_component(value)
        elif kind == "frame":
            self.controller.set_frame(value)

    # -- the frame on screen ---------------------------------------------------------------------
    def show_frame(self) -> None:
        """Show the current frame: images, outlines, overlays, pose, pose status."""
        c, s = self.controller, self.controller.session
        frame = c.frame
        if frame is None:
            return
        images = []
        for view in range(s.n_views):
            try:
                images.append(s.image(frame, view))
                self.panels[view].placeholder = ""
            except InputError as exc:
                self.statusBar().showMessage(str(exc), 10000)
                self.last_error = str(exc)
                images.append(None)
                if view < len(self.panels):
                    self.panels[view].placeholder = f"No image for frame {frame}:\n{exc}"
        for view, panel in enumerate(self.panels):
            panel.set_image(images[view] if view < len(images) else None, key=(frame, view))
            for name in s.components():
                key = c.outline_key(view, name)
                panel.set_outline(name, s.outline_points(key), key)
        if self.scene_widget is not None:
            self.scene_widget.scene.set_images(images)
        for name in s.components():
            self._show_pose(name)
        self._show_rays()
        if self.scene_widget is not None and getattr(self, "_camera_pending", False):
            self._camera_pending = False
            self.scene_widget.scene.camera_preset("implant")
        self._show_pose_status()
        self.timeline.set_current(frame)
        self.frame_label.setText(f"Frame {frame} ({c.frame_index + 1}/{len(s.frames)})")
        self.frame_shown.emit(frame)

    def _show_rays(self) -> None:
        """Rays in the 3D scene through the active component's image outline."""
        if self.scene_widget is None:
            return
        c, s = self.controller, self.controller.session
        for view in range(s.n_views):
            self.scene_widget.scene.set_rays(view, s.outline_points(c.outline_key(view)))

    def _show_pose(self, component: str) -> None:
        """Overlays and 3D model of one component at its current pose."""
        c, s = self.controller, self.controller.session
        pose = s.pose(component, c.frame)
        record = s.pose_record(component, c.frame)
        for panel in self.panels:
            panel.set_model_flagged(component, record is not None and record.needs_review)
        self._show_model_outline(component, pose)
        if self.scene_widget is not None:
            self.scene_widget.scene.set_pose(component, pose)
            self.scene_widget.scene.render()
        if component == c.component:
            self.pose_editor.set_pose(pose)
            self.pose_editor.set_uncertainty(_pose_sd(record))

    def _show_model_outline(self, component: str, pose, outlines=None) -> None:
        c, s = self.controller, self.controller.session
        try:
            mesh = s.mesh(component)
        except (InputError, KeyError):
            for panel in self.panels:  # no model: no overlay (never a stale one)
                panel.set_model_outline(component, None)
            return
        for view, panel in enumerate(self.panels[:s.n_views]):
            try:
                points = outlines[view] if outlines is not None else predicted_outline(
                    mesh, pose, s.views[view], jobs.OVERLAY_SPACING_PX)
            except ValueError:  # e.g. the model behind the source
                panel.set_model_outline(component, None)
                continue
            distances = None
            spline = s.spline(c.outline_key(view, component))
            if spline is not None:
                try:
                    distances = spline.closest(points)[0]
                except (OutlineError, ValueError):
                    distances = None
            panel.set_model_outline(component, points, distances)

    def _show_pose_status(self) -> None:
        """The matcher panel's account of every component's pose in the frame on screen."""
        c, s = self.controller, self.controller.session
        if c.frame is None:
            return
        lines = []
        for name in s.components():
            text, level = describe_pose(name, s.pose_record(name, c.frame))
            lines.append((text, level, name == c.component))
        self.matcher.show_poses(lines)
        self._refresh_accept_state()
        record = s.pose_record(c.component, c.frame)
        if not self.runner.is_running():  # a running task draws its own plot
            self.matcher.plot.set_values(record.match.history if record is not None and record.match else [])

    def _frame_note(self, frame: int) -> str:
        """Why a frame needs review, for the timeline's tooltip ("" when it does not)."""
        s = self.controller.session
        notes = []
        for name in s.components():
            record = s.pose_record(name, frame)
            if record is not None and record.needs_review:
                notes.append(describe_pose(name, record)[0])
        return "\n".join(notes)

    # -- keeping in step with the session ----------------------------------------------------------
    def _component_changed(self, name: str) -> None:
        c, s = self.controller, self.controller.session
        self.component_combo.blockSignals(True)
        self.component_combo.setCurrentText(name)
        self.component_combo.blockSignals(False)
        for action in self.component_actions.actions():
            action.setChecked(action.text() == name)
        for panel in self.panels:
            panel.set_active_component(name)
        known = name in s.components()
        self.pose_editor.set_component(name if known else None)
        if known and c.frame is not None:
            self.pose_editor.set_pose(s.pose(name, c.frame))
            self.pose_editor.set_uncertainty(_pose_sd(s.pose_record(name, c.frame)))
            self._show_pose_status()
        if self.scene_widget is not None and known:
            self.scene_widget.enable_gizmo(name)
            self._show_rays()

    def _pose_changed(self, frame: int, component: str) -> None:
        c = self.controller
        if frame == c.frame:
            self._show_pose(component)
            self._show_pose_status()
        self._frame_state_changed(frame)

    def _outline_changed(self, key, component: str) -> None:
        c, s = self.controller, self.controller.session
        frame, view, _ = key
        if frame == c.frame and view < len(self.panels):
            self.panels[view].set_outline(component, s.outline_points(key), key)
            if not self._deferred_overlay:
                self._show_model_outline(component, s.pose(component, frame))
            if component == c.component:
                self._show_rays()
        self._frame_state_changed(frame)

    def _frame_state_changed(self, frame: int) -> None:
        s = self.controller.session
        state = s.frame_state(frame)
        self.timeline.set_state(frame, state)
        self.timeline.set_note(frame, self._frame_note(frame) if state == FrameState.NEEDS_REVIEW else "")


def _pose_sd(record):
    """The standard deviations stored with a record's match (None without a match)."""
    if record is None or record.match is None:
        return None
    return record.match.quality.get("sd")
