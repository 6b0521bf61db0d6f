"""Showing the session in the main window: the frame on screen (images, outlines, model
overlays, 3D scene, the pose panel's values) and the pose status of its components, kept
in step with the session's events.

``SessionView`` is given what it draws into (the image panels, the 3D scene, the matcher
and pose panels, the status bar's labels) and what it tells (``frame_shown``; a callable
offering to locate a missing model; ``pose_status_shown``, after which the Accept action
is judged); it reads the session (``controller.session``) and never changes it. The
Session and Frames panels have presenters of their own (``actions.session_tree``,
``actions.frames``). Frames are frame numbers throughout.
"""
from __future__ import annotations

from collections.abc import Callable
from contextlib import contextmanager
from types import SimpleNamespace

from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtGui import QColor

from fluorogui.core.matching.loop import predicted_outline
from fluorogui.core.outlines.spline import OutlineError
from fluorogui.gui import jobs
from fluorogui.gui.notices import Notices
from fluorogui.gui.panels.matcher_panel import MatcherPanel, describe_pose
from fluorogui.gui.panels.pixel_value import RawPixels, format_value
from fluorogui.gui.panels.pose_editor import PoseEditor
from fluorogui.io.errors import InputError

COMPONENT_COLOURS = {"femoral": QColor(90, 170, 255), "tibial": QColor(110, 220, 120)}


class SessionView(QObject):
    """What a main window shows of the session, kept in step with the controller's signals."""

    #: the matcher panel now gives the pose status of the frame on screen
    pose_status_shown = Signal()

    def __init__(self, controller, panels: list, scene_widget, matcher: MatcherPanel, pose_editor: PoseEditor,
                 notices: Notices, *, labels: SimpleNamespace, frame_shown, offer_locate: Callable,
                 is_running: Callable[[], bool]) -> None:
        """``scene_widget``: the 3D scene (None without one); ``labels``: the status bar's
        ``cursor`` and ``frame`` labels; ``frame_shown``: the signal emitted (with the frame
        number) once a frame is on screen; ``offer_locate(component, error)``: offers to
        find a model file that cannot be loaded; ``is_running``: whether a task runs."""
        super().__init__(notices.parent_widget)
        self.controller = c = controller
        self.panels = panels
        self.scene_widget = scene_widget
        self.matcher = matcher
        self.pose_editor = pose_editor
        self.notices = notices
        self.labels = labels
        self.frame_shown = frame_shown
        self._offer_locate = offer_locate
        self._is_running = is_running
        self.raw_pixels = RawPixels()
        self._camera_pending = False
        self._deferred_overlay = False
        for panel in self.panels:
            panel.cursor_moved.connect(lambda u, v, value, view=panel.view_index: self.show_cursor(u, v, value, view))
        c.project_replaced.connect(self._project_replaced)
        c.frame_changed.connect(lambda _frame: self.show_frame())
        c.component_changed.connect(self._component_changed)
        c.pose_changed.connect(self._pose_changed)
        c.outline_changed.connect(self._outline_changed)
        c.model_changed.connect(self._model_changed)

    @property
    def session(self):
        return self.controller.session

    # -- a new project ---------------------------------------------------------------------------
    def _project_replaced(self) -> None:
        c, s = self.controller, self.controller.session
        names = s.components()
        for view, panel in enumerate(self.panels):
            # a single-plane session: one panel across the width (no session: both, with the hint)
            panel.setVisible(view < s.n_views or s.n_views == 0)
            panel.forget_images()  # nothing of the last session's view: its zoom, its erased edges
        missing = []
        if self.scene_widget is not None:
            scene = self.scene_widget.scene
            self.scene_widget.set_views(s.views)
            for name in scene.components:
                if name not in names:
                    scene.remove_model(name)  # the previous project's component
        for name in names:
            error = self.load_scene_model(name)
            if error is not None:
                missing.append((name, error))
        self.matcher.set_settings(s.settings.match)
        self.matcher.show_summary("")
        self._camera_pending = True
        self._component_changed(c.component)
        if missing:  # after the window shows the project: offer to relink each missing model
            offer = self._offer_locate
            QTimer.singleShot(0, lambda: [offer(name, error) for name, error in missing])

    def load_scene_model(self, name: str) -> InputError | None:
        """Put a component's mesh in the 3D scene; on failure remove what was there (and its
        overlays: never a stale one) and return the error."""
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
            colour = COMPONENT_COLOURS.get(name, QColor(200, 200, 200)).getRgbF()[:3]
            self.scene_widget.scene.set_model(name, vertices, faces, colour)
        return None

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
                self.notices.error(str(exc))
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
            self.show_pose(name)
        self.show_rays()
        if self.scene_widget is not None and self._camera_pending:
            self._camera_pending = False
            self.scene_widget.scene.camera_preset("implant")
        self.show_pose_status()
        self.labels.frame.setText(f"Frame {frame} ({c.frame_index + 1}/{len(s.frames)})")
        self.frame_shown.emit(frame)

    def show_rays(self) -> None:
        """Rays in the 3D scene through the active component's image outline."""
        if self.scene_widget is None:
            return
        c, s = self.controller, self.controller.session
        for view in range(s.n_views):
            self.scene_widget.scene.set_rays(view, s.outline_points(c.outline_key(view)))

    def show_pose(self, component: str) -> None:
        """Overlays and 3D model of one component at its current pose."""
        c, s = self.controller, self.controller.session
        pose = s.pose(component, c.frame)
        record = s.pose_record(component, c.frame)
        for panel in self.panels:
            panel.set_model_flagged(component, record is not None and record.needs_review)
        self.show_model_outline(component, pose)
        if self.scene_widget is not None:
            self.scene_widget.scene.set_pose(component, pose)
            self.scene_widget.scene.render()
        if component == c.component:
            self.pose_editor.set_pose(pose)
            self.pose_editor.set_uncertainty(*_pose_sds(record))

    def show_model_outline(self, component: str, pose, outlines=None) -> None:
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

    def show_pose_status(self) -> None:
        """The matcher panel's account of every component's pose in the frame on screen."""
        c, s = self.controller, self.controller.session
        if c.frame is None:
            return
        lines = []
        for name in s.components():
            text, level = describe_pose(name, s.pose_record(name, c.frame))
            lines.append((text, level, name == c.component))
        self.matcher.show_poses(lines)
        record = s.pose_record(c.component, c.frame)
        if not self._is_running():  # a running task draws its own plot
            self.matcher.plot.set_values(record.match.history if record is not None and record.match else [])
        self.pose_status_shown.emit()

    # -- keeping in step with the session ----------------------------------------------------------
    def _component_changed(self, name: str) -> None:
        c, s = self.controller, self.controller.session
        for panel in self.panels:
            panel.set_active_component(name)
        known = name in s.components()
        self.pose_editor.set_component(name if known else None)
        if known and c.frame is not None:
            self.pose_editor.set_pose(s.pose(name, c.frame))
            self.pose_editor.set_uncertainty(*_pose_sds(s.pose_record(name, c.frame)))
            self.show_pose_status()
        if self.scene_widget is not None and known:
            self.scene_widget.enable_gizmo(name)
            self.show_rays()

    def _pose_changed(self, frame: int, component: str) -> None:
        c = self.controller
        if frame == c.frame:
            self.show_pose(component)
            self.show_pose_status()

    def _outline_changed(self, key, component: str) -> None:
        c, s = self.controller, self.controller.session
        frame, view, _ = key
        if frame == c.frame and view < len(self.panels):
            self.panels[view].set_outline(component, s.outline_points(key), key)
            if not self._deferred_overlay:
                self.show_model_outline(component, s.pose(component, frame))
            if component == c.component:
                self.show_rays()

    @contextmanager
    def one_overlay_refresh(self):
        """Within: outline changes leave the model overlays alone (a result stores several
        outlines and a pose; the pose change redraws the overlay once)."""
        self._deferred_overlay = True
        try:
            yield
        finally:
            self._deferred_overlay = False

    def _model_changed(self, name: str) -> None:
        """A component's mesh file changed (relinked, or undone): reload it everywhere."""
        if self.load_scene_model(name) is None and self.controller.frame is not None:
            self.show_pose(name)
            self.show_pose_status()

    def show_cursor(self, u: float, v: float, value: float, view: int | None = None) -> None:
        """Cursor position and the value stored in the image file at that pixel (the
        panels hold images scaled to [0, 1]; the file's own number is what users know)."""
        raw = None
        c, s = self.controller, self.controller.session
        if view is not None and c.frame is not None and view < s.n_views:
            path = s.image_path(c.frame, view)
            image = self.panels[view].image()
            if path is not None and image is not None:
                raw = self.raw_pixels.value_at(path, u, v, image.shape)
        if raw is not None:
            text = format_value(raw)
        elif value == value:  # not NaN: no file value, show the scaled one
            text = f"{value:.4g}"
        else:
            text = "–"
        self.labels.cursor.setText(f"u {u:.1f}  v {v:.1f}  value {text}")


def _pose_sds(record) -> tuple:
    """The standard deviations stored with a record's match: of the pose's six values and of
    the body's own moves and turns (each None without a match, or where it kept none)."""
    if record is None or record.match is None:
        return None, None
    return record.match.quality.get("sd"), record.match.quality.get("sd_body")
