"""The main window: two image panels, the 3D fluoroscope, docks, menus and what they show.

Thin by design: the project lives in the workflow's ``Session`` (``controller.session``);
every change goes through it (undoable, announced by the ``SessionController``'s
signals, the Qt undo stack only mirrors its history); long work runs the session's jobs
in ``TaskRunner``. This module builds the window and wires it up; showing the session
(``session_view``), the session files (``session_files``) and the long tasks
(``match_control``) are mixins of their own.
"""
from __future__ import annotations

from PySide6.QtCore import QSettings, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QActionGroup, QKeySequence
from PySide6.QtWidgets import (
    QApplication,
    QComboBox,
    QDockWidget,
    QFrame,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QMessageBox,
    QScrollArea,
    QSlider,
    QSplitter,
    QTreeWidget,
    QWidget,
)

from fluorogui.gui import theme
from fluorogui.gui.controller import SessionController
from fluorogui.gui.actions.help import HelpActions
from fluorogui.gui.panels.image_panel import ImagePanel, Tool
from fluorogui.gui.actions.knee import KneeActions
from fluorogui.gui.actions.tasks import MatchControl
from fluorogui.gui.panels.matcher_panel import MatcherPanel
from fluorogui.gui.dialogs.missing_files import MissingFiles
from fluorogui.gui.panels.pixel_value import RawPixels, format_value
from fluorogui.gui.panels.pose_editor import PoseEditor
from fluorogui.gui.actions.review import ReviewActions
from fluorogui.gui.actions.files import SessionFiles
from fluorogui.gui.session_view import COMPONENT_COLOURS, SessionView
from fluorogui.gui.panels.timeline import Timeline, TimelineLegend
from fluorogui.gui.worker import TaskRunner
from fluorogui.io.errors import InputError
from fluorogui.workflow.session import ORIENTATION_PRESETS

AUTOSAVE_MS = 3 * 60 * 1000
NO_SESSION_HINT = ("No session open.\nFile → Open… (Ctrl+O) opens a project,\nFile → New session (Ctrl+N) "
                   "imports images,\nFile → Open the demo session to try it out.")
TOOLS = (
    (Tool.NAVIGATE, "navigate", "Navigate", "N", "Pan and zoom (wheel zooms at the cursor, right-drag sets window/level)"),
    (Tool.PICK_CONTOUR, "pick", "Pick contour", "P", "Click an edge contour to take it as the outline (Shift adds one)"),
    (Tool.MOVE, "move", "Move point", "M", "Drag an outline point"),
    (Tool.INSERT, "insert", "Insert point", "I", "Click to insert a point into the nearest segment"),
    (Tool.DELETE, "delete", "Delete point", "D", "Click to delete the nearest point"),
    (Tool.ERASE, "erase", "Erase", "E", "Brush away edges and outline points"),
    (Tool.LASSO, "lasso", "Lasso delete", "L", "Draw around outline points to delete them"),
    (Tool.CLOSE_GAP, "close_gap", "Close gap", "G", "Click two outline points to bridge the gap between them"),
    (Tool.PLACE, "place", "Place model", "C", "Click the component in view 1 and view 2 to place the model there"),
)


class MainWindow(SessionFiles, SessionView, MatchControl, ReviewActions, HelpActions, MissingFiles, KneeActions,
                 QMainWindow):
    """The fluorogui main window."""

    frame_shown = Signal(int)  # frame number, emitted after its images and overlays are on screen

    def __init__(self, settings: QSettings | None = None, with_3d: bool = True,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.settings = settings or QSettings("fluorogui", "fluorogui")
        self.controller = SessionController(self)
        self.runner = TaskRunner(self)
        self.place_clicks: dict[int, tuple[float, float]] = {}
        self.last_error = ""
        self._init_tasks()
        self.last_cancel_latency: float | None = None
        self._last_live_3d = 0.0
        self._deferred_overlay = False
        self.last_place_miss: float | None = None
        self.raw_pixels = RawPixels()
        self.setWindowIcon(theme.icon("app"))
        self.setAcceptDrops(True)
        self.setDockNestingEnabled(True)

        self.panels = [ImagePanel(i) for i in range(2)]
        splitter = QSplitter(Qt.Orientation.Horizontal)
        for panel in self.panels:
            panel.edit_sink = self.controller.apply_edit
            panel.point_clicked.connect(self._place_click)
            panel.cursor_moved.connect(lambda u, v, value, view=panel.view_index: self._show_cursor(u, v, value, view))
            for name, colour in COMPONENT_COLOURS.items():
                panel.set_component_colour(name, colour)
            panel.placeholder = NO_SESSION_HINT
            splitter.addWidget(panel)
        self.setCentralWidget(splitter)

        self.scene_widget = None
        if with_3d:
            from fluorogui.gui.scene.scene_widget import Scene3DWidget

            self.scene_widget = Scene3DWidget(self)
            self.scene_widget.rays_button.setChecked(False)  # rays on demand: they hide the models
            self.scene_widget.pose_dragged.connect(
                lambda name, pose: self.session.set_pose(name, self.controller.frame, pose, text="Drag model",
                                                         mergeable=True))
        self.pose_editor = PoseEditor()
        self.matcher = MatcherPanel()
        self.timeline = Timeline()
        self.tree = QTreeWidget()
        self.tree.setHeaderHidden(True)
        self.tree.itemActivated.connect(self._tree_activated)
        self.tree.itemClicked.connect(self._tree_activated)
        self._build_docks()
        self._build_actions()
        self._build_status_bar()
        self._connect()
        self.autosave_timer = QTimer(self)
        self.autosave_timer.setInterval(int(self.settings.value("autosave_ms", AUTOSAVE_MS)))
        self.autosave_timer.timeout.connect(self.autosave)
        self.autosave_timer.start()
        self._restore_layout()
        self.focus_frame = theme.install_focus_frame(self)
        self._refresh_title()
        self.pose_editor.set_component(None)

    # -- construction ----------------------------------------------------------------------
    def _dock(self, title: str, widget: QWidget, area, name: str, scroll: bool = False) -> QDockWidget:
        """A dock; with ``scroll`` its content scrolls when the window is too small for it
        (a laptop screen) instead of squeezing or overlapping."""
        dock = QDockWidget(title, self)
        dock.setObjectName(name)
        if scroll:
            area_widget = QScrollArea()
            area_widget.setObjectName(f"{name}Scroll")
            area_widget.setWidgetResizable(True)
            area_widget.setFrameShape(QFrame.Shape.NoFrame)
            area_widget.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAsNeeded)
            area_widget.setWidget(widget)
            area_widget.setMinimumSize(160, 90)
            widget = area_widget
        dock.setWidget(widget)
        self.addDockWidget(area, dock)
        return dock

    def _build_docks(self) -> None:
        right = Qt.DockWidgetArea.RightDockWidgetArea
        if self.scene_widget is not None:
            self.scene_dock = self._dock("3D scene", self.scene_widget, right, "sceneDock")
        self.matcher_dock = self._dock("Matcher", self.matcher, right, "matcherDock", scroll=True)
        self.pose_dock = self._dock("Pose", self.pose_editor, right, "poseDock", scroll=True)
        self.session_dock = self._dock("Session", self.tree, right, "sessionDock")
        self.tabifyDockWidget(self.matcher_dock, self.pose_dock)
        self.tabifyDockWidget(self.pose_dock, self.session_dock)
        self._build_knee_dock(right)
        self.tabifyDockWidget(self.session_dock, self.knee_dock)
        self.matcher_dock.raise_()
        frames = QWidget()
        row = QHBoxLayout(frames)
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(self.timeline, 1)
        self.timeline_legend = TimelineLegend()
        row.addWidget(self.timeline_legend)
        self.timeline_dock = self._dock("Frames", frames, Qt.DockWidgetArea.BottomDockWidgetArea, "timelineDock")
        self.timeline_dock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable)

    def _action(self, text: str, slot, shortcut=None, icon: str | None = None, tip: str = "") -> QAction:
        action = QAction(text, self)
        if shortcut is not None:
            action.setShortcut(QKeySequence(shortcut))
        if icon:
            action.setIcon(theme.icon(icon))
        if tip:
            action.setToolTip(tip)
            action.setStatusTip(tip)
        action.triggered.connect(slot)
        self.addAction(action)
        return action

    def calibrate_fluoroscope(self) -> None:
        """The calibration wizard (distortion from plates, geometry from a bead phantom)."""
        from fluorogui.gui.dialogs.calibration_wizard import CalibrationWizard

        wizard = CalibrationWizard(self)
        if wizard.exec():
            self.statusBar().showMessage("Wrote " + ", ".join(str(p) for p in wizard.written), 10000)

    def _build_actions(self) -> None:
        c = self.controller
        menu = self.menuBar()
        file_menu = menu.addMenu("&File")
        self.open_action = self._action("&Open…", lambda: self.open_project(), QKeySequence.StandardKey.Open, "open",
                                        "Open a fluorogui project (Ctrl+O)")
        self.new_action = self._action("&New session from images and calibration…", lambda: self.import_session(),
                                       QKeySequence.StandardKey.New)
        self.import_action = self.new_action
        self.demo_action = self._action("Open the &demo session", self.open_demo)
        self.save_action = self._action("&Save", self.save, QKeySequence.StandardKey.Save, "save",
                                        "Save the session (Ctrl+S)")
        self.save_as_action = self._action("Save &as…", self.save_as, QKeySequence.StandardKey.SaveAs)
        self.quit_action = self._action("&Quit", self.close, QKeySequence.StandardKey.Quit)
        self.recent_menu = file_menu.addMenu("Open &recent")
        for a in (self.new_action, self.open_action, self.demo_action):
            file_menu.addAction(a)
        file_menu.insertMenu(self.demo_action, self.recent_menu)
        file_menu.addSeparator()
        file_menu.addAction(self.save_action)
        file_menu.addAction(self.save_as_action)
        file_menu.addSeparator()
        self.calibrate_action = self._action("&Calibrate fluoroscope (plate, beads)…", self.calibrate_fluoroscope)
        file_menu.addAction(self.calibrate_action)
        file_menu.addSeparator()
        file_menu.addAction(self.quit_action)
        self._knee_menu_actions(file_menu, self.quit_action)

        edit_menu = menu.addMenu("&Edit")
        self.undo_action = c.undo_stack.createUndoAction(self, "&Undo")
        self.undo_action.setShortcut(QKeySequence.StandardKey.Undo)
        self.redo_action = c.undo_stack.createRedoAction(self, "&Redo")
        self.redo_action.setShortcuts([QKeySequence("Ctrl+Shift+Z"), QKeySequence.StandardKey.Redo])
        self.addAction(self.undo_action)  # listed with the window's shortcuts (F1)
        self.addAction(self.redo_action)
        edit_menu.addAction(self.undo_action)
        edit_menu.addAction(self.redo_action)
        edit_menu.addSeparator()
        self.tool_group = QActionGroup(self)
        self.tool_actions: dict[Tool, QAction] = {}
        for tool, icon_name, text, key, tip in TOOLS:
            action = self._action(text, lambda _=False, t=tool: self.set_tool(t), key, icon_name, f"{tip} ({key})")
            action.setCheckable(True)
            self.tool_group.addAction(action)
            edit_menu.addAction(action)
            self.tool_actions[tool] = action
        self.tool_actions[Tool.NAVIGATE].setChecked(True)
        edit_menu.addSeparator()
        self.clear_outline_action = self._action("Clear outline of the active component", self.clear_outlines)
        edit_menu.addAction(self.clear_outline_action)

        view_menu = menu.addMenu("&View")
        self.fit_action = self._action("&Fit images", self.fit_images, "F", "fit", "Fit both images to their panels")
        self.edges_action = self._action("Show &edges", self.toggle_edges, "Ctrl+E", "edges",
                                         "Show Canny edges (thresholds on the toolbar)")
        self.edges_action.setCheckable(True)
        view_menu.addAction(self.fit_action)
        view_menu.addAction(self.edges_action)
        view_menu.addSeparator()
        for dock in [d for d in self.findChildren(QDockWidget)]:
            view_menu.addAction(dock.toggleViewAction())
        view_menu.addSeparator()
        theme_menu = view_menu.addMenu("&Theme")
        self.theme_group = QActionGroup(self)
        for name in theme.THEMES:
            action = QAction(name.capitalize(), self, checkable=True)
            action.triggered.connect(lambda _=False, n=name: self.set_theme(n))
            self.theme_group.addAction(action)
            theme_menu.addAction(action)
            if name == self.settings.value("theme", "system"):
                action.setChecked(True)

        model_menu = menu.addMenu("&Model")
        self.component_actions = QActionGroup(self)
        self.component_menu = model_menu.addMenu("Active &component")
        self.orient_menu = model_menu.addMenu("&Orientation preset")
        for text, angles in ORIENTATION_PRESETS:
            action = QAction(text, self)
            action.triggered.connect(lambda _=False, a=angles: self._orient(a))
            self.orient_menu.addAction(action)
        model_menu.addAction(self.tool_actions[Tool.PLACE])
        self.find_action = self._action("&Find implants automatically", lambda: self.find_implants(), "Ctrl+F",
                                        tip="Locate every component in this frame's images (Ctrl+F)")
        model_menu.addAction(self.find_action)
        nudges = ((Qt.Key.Key_Left, 0, -1), (Qt.Key.Key_Right, 0, 1), (Qt.Key.Key_Down, 1, -1),
                  (Qt.Key.Key_Up, 1, 1), (Qt.Key.Key_PageDown, 2, -1), (Qt.Key.Key_PageUp, 2, 1))
        for key, axis, direction in nudges:
            self._action(f"Move {'xyz'[axis]} {'+' if direction > 0 else '-'}",
                         lambda _=False, a=axis, d=direction: self.pose_editor.nudge(a, d),
                         QKeySequence(Qt.KeyboardModifier.ControlModifier | key))
            self._action(f"Turn {('alpha', 'beta', 'gamma')[axis]} {'+' if direction > 0 else '-'}",
                         lambda _=False, a=axis + 3, d=direction: self.pose_editor.nudge(a, d),
                         QKeySequence(Qt.KeyboardModifier.ControlModifier | Qt.KeyboardModifier.ShiftModifier | key))

        match_menu = menu.addMenu("M&atch")
        self.run_action = self._action("&Match active component", lambda: self.run_match(), "F5", "match",
                                       "Match the active component in this frame (F5)")
        self.run_both_action = self._action("Match &both components", lambda: self.match_both(), "Ctrl+F5",
                                            "match_both", "Match every component in this frame (Ctrl+F5)")
        self.cancel_action = self._action("&Cancel", self.runner.cancel, "Esc", "cancel",
                                          "Stop the running task (Esc)")
        self.cancel_action.setEnabled(False)
        self.track_action = self._action("&Track following frames", lambda: self.track_frames(), "Shift+F5",
                                         tip="Track the active component through the following frames (Shift+F5)")
        self.track_both_action = self._action("Track &both through following frames", lambda: self.track_both(),
                                              "Ctrl+Shift+F5", "track_both",
                                              "Track every component through the following frames (Ctrl+Shift+F5)")
        self.accept_action = self._action("&Accept pose", self.accept_pose, "Ctrl+Return", "accept",
                                          "Accept the active component's pose in this frame (Ctrl+Return)")
        self.unaccept_action = self._action("&Un-accept pose", self.unaccept_pose, "Ctrl+Shift+Return",
                                            tip="Take back the acceptance of the active component's pose "
                                                "(Ctrl+Shift+Return)")
        self.next_action = self._action("&Next frame", lambda: self.step_frame(1), "PgDown")
        self.prev_action = self._action("&Previous frame", lambda: self.step_frame(-1), "PgUp")
        self.first_action = self._action("&First frame", lambda: self.go_to_end(first=True), "Home")
        self.last_action = self._action("&Last frame", lambda: self.go_to_end(first=False), "End")
        self.next_component_action = self._action("Next &component", self.cycle_component, "K",
                                                  tip="Make the next component the active one (K)")
        for a in (self.run_action, self.run_both_action, self.cancel_action, self.track_action,
                  self.track_both_action, self.accept_action, self.unaccept_action):
            match_menu.addAction(a)
        match_menu.addSeparator()
        for a in (self.next_action, self.prev_action, self.first_action, self.last_action):
            match_menu.addAction(a)
        model_menu.insertAction(self.orient_menu.menuAction(), self.next_component_action)

        from fluorogui.gui.dialogs.tour import start_tour

        self.tour_action = self._action("Guided &tour", lambda: start_tour(self, force=True),
                                        tip="A one-minute tour of the window")
        self._build_help_menu(menu)

        bar = self.addToolBar("Main")
        bar.setObjectName("mainToolbar")
        bar.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonIconOnly)
        for a in (self.open_action, self.save_action):
            bar.addAction(a)
        bar.addSeparator()
        bar.addWidget(QLabel(" Component "))
        self.component_combo = QComboBox()
        self.component_combo.setToolTip("The component whose outline and pose you edit")
        self.component_combo.currentTextChanged.connect(lambda t: t and self.controller.set_component(t))
        bar.addWidget(self.component_combo)
        bar.addSeparator()
        for tool, *_ in TOOLS:
            bar.addAction(self.tool_actions[tool])
        bar.addSeparator()
        bar.addAction(self.fit_action)
        bar.addAction(self.edges_action)
        self.low_slider, self.high_slider = QSlider(Qt.Orientation.Horizontal), QSlider(Qt.Orientation.Horizontal)
        for slider, value, tip in ((self.low_slider, 10, "Canny low threshold (% of the strong-edge gradient)"),
                                   (self.high_slider, 30, "Canny high threshold (% of the strong-edge gradient)")):
            slider.setRange(1, 100)
            slider.setValue(int(self.settings.value(f"canny/{'low' if slider is self.low_slider else 'high'}",
                                                    value)))
            slider.setFixedWidth(80)
            slider.setToolTip(tip)
            slider.valueChanged.connect(self._thresholds_changed)
            bar.addWidget(slider)
        bar.addSeparator()
        for a in (self.run_action, self.run_both_action, self.track_both_action, self.cancel_action,
                  self.accept_action):
            bar.addAction(a)

    def _build_status_bar(self) -> None:
        self.tool_label = QLabel("")  # what the current tool does, always in view
        self.tool_label.setObjectName("toolHint")
        self.statusBar().addWidget(self.tool_label, 1)
        self._show_tool_hint(Tool.NAVIGATE)
        self.cursor_label = QLabel("")
        self.frame_label = QLabel("")
        self.statusBar().addPermanentWidget(self.cursor_label)
        self.statusBar().addPermanentWidget(self.frame_label)

    def _connect(self) -> None:
        c = self.controller
        c.project_replaced.connect(self._project_replaced)
        c.frame_changed.connect(lambda _frame: self.show_frame())
        c.component_changed.connect(self._component_changed)
        c.pose_changed.connect(self._pose_changed)
        c.outline_changed.connect(self._outline_changed)
        c.dirty_changed.connect(lambda dirty: self.setWindowModified(dirty))
        c.path_changed.connect(lambda _p: self._refresh_title())
        c.model_changed.connect(self._model_changed)
        self.pose_editor.pose_edited.connect(
            lambda pose: c.session.set_pose(c.component, c.frame, pose, text="Edit pose", mergeable=True))
        self.timeline.frame_selected.connect(c.set_frame)
        m = self.matcher
        m.run_requested.connect(lambda: self.run_match())
        m.run_both_requested.connect(lambda: self.match_both())
        m.cancel_requested.connect(self.runner.cancel)
        m.track_requested.connect(lambda: self.track_frames())
        m.track_both_requested.connect(lambda: self.track_both())
        m.accept_requested.connect(self.accept_pose)
        m.unaccept_requested.connect(self.unaccept_pose)
        m.place_requested.connect(lambda: self.find_implants())
        m.settings_edited.connect(self._settings_edited)
        r = self.runner
        r.running_changed.connect(self._running_changed)
        r.progress.connect(self._task_progress)
        r.item.connect(self._task_item)
        r.finished.connect(self._task_finished)
        r.cancelled.connect(self._task_cancelled)
        r.failed.connect(self._task_failed)

    # -- settings and layout ---------------------------------------------------------------
    def _restore_layout(self) -> None:
        geometry = self.settings.value("window/geometry")
        state = self.settings.value("window/state")
        if geometry is not None:
            self.restoreGeometry(geometry)
        else:
            self.resize(1280, 800)
        if state is not None:
            self.restoreState(state)
        elif self.scene_widget is not None:
            QTimer.singleShot(0, self._share_right_column)
        self._refresh_recent()

    def _share_right_column(self) -> None:
        """First start: the 3D scene takes 40 % of the right column, the tabs the rest."""
        height = max(self.height() - 160, 300)
        self.resizeDocks([self.scene_dock, self.matcher_dock], [int(height * 0.4), int(height * 0.6)],
                         Qt.Orientation.Vertical)

    def _save_layout(self) -> None:
        self.settings.setValue("window/geometry", self.saveGeometry())
        self.settings.setValue("window/state", self.saveState())
        self.settings.setValue("canny/low", self.low_slider.value())
        self.settings.setValue("canny/high", self.high_slider.value())

    def set_theme(self, name: str) -> None:
        self.settings.setValue("theme", name)
        app = QApplication.instance()
        if app is not None:
            theme.apply_theme(app, name)

    # -- session life cycle ----------------------------------------------------------------
    def _refresh_title(self) -> None:
        path = self.controller.path
        name = path.name if path else "untitled"
        if self.controller.project.settings.get("demo"):
            name += " (demo)"
        if self.controller.read_only:
            name += " (read-only)"
        self.setWindowTitle(f"{name}[*] — fluorogui")
        self.setWindowModified(self.controller.dirty)

    def _warn(self, title: str, message: str) -> None:
        self.last_error = message
        self.statusBar().showMessage(message, 10000)
        QMessageBox.warning(self, title, message)

    def closeEvent(self, event) -> None:  # noqa: N802 (Qt override)
        if not self.maybe_save():
            event.ignore()
            return
        if self.runner.is_running():
            self.runner.cancel()
            self.runner.wait(5000)
        self._save_layout()
        self.recovery_path().unlink(missing_ok=True)
        self.controller.close()
        if self.scene_widget is not None:
            self.scene_widget.close()
        event.accept()

    def _show_cursor(self, u: float, v: float, value: float, view: int | None = None) -> None:
        """Cursor position and the value stored in the image file at that pixel (the
        panels hold images scaled to [0, 1]; the file's own number is what users know)."""
        raw = None
        c = self.controller
        if view is not None and c.frame is not None and view < self.session.n_views:
            path = self.session.image_path(c.frame, view)
            image = self.panels[view].image()
            if path is not None and image is not None:
                raw = self.raw_pixels.value_at(path, u, v, image.shape)
        if raw is not None:
            text = format_value(raw)
        elif value == value:  # not NaN: no file value, show the scaled one
            text = f"{value:.4g}"
        else:
            text = "–"
        self.cursor_label.setText(f"u {u:.1f}  v {v:.1f}  value {text}")

    # -- editing ---------------------------------------------------------------------------
    def _show_tool_hint(self, tool: Tool) -> None:
        text, key, tip = next((t, k, h) for tl, _i, t, k, h in TOOLS if tl == tool)
        self.tool_label.setText(f"{text} ({key}): {tip}")

    def set_tool(self, tool: Tool) -> None:
        for panel in self.panels:
            panel.set_tool(tool)
        self.tool_actions[tool].setChecked(True)
        self._show_tool_hint(tool)
        if tool == Tool.PLACE:
            self.place_clicks.clear()
            self.statusBar().showMessage(
                f"Click the {self.controller.component} component in view 1, then in view 2", 10000)

    def fit_images(self) -> None:
        for panel in self.panels:
            panel.fit()

    def toggle_edges(self, on: bool | None = None) -> None:
        on = self.edges_action.isChecked() if on is None else on
        self.edges_action.setChecked(on)
        self._thresholds_changed()
        for panel in self.panels:
            panel.set_edges_visible(on)

    def _thresholds_changed(self, _value=None) -> None:
        low, high = self.low_slider.value() / 100, self.high_slider.value() / 100
        if low > high:
            low, high = high, low
        if self.edges_action.isChecked():
            for panel in self.panels:
                panel.set_canny_thresholds(low, high)

    def clear_outlines(self) -> None:
        c, s = self.controller, self.controller.session
        if c.frame is None:
            return
        s.history.begin_macro(f"Clear {c.component} outlines")
        try:
            for view in range(s.n_views):
                if s.outline_record(c.outline_key(view)) is not None:
                    s.set_outline(c.outline_key(view), None, f"Clear {c.component} outline")
        finally:
            s.history.end_macro()

    def _place_click(self, view: int, u: float, v: float) -> None:
        c = self.controller
        self.place_clicks[view] = (u, v)
        if len(self.place_clicks) < 2:
            other = 2 if view == 0 else 1
            self.statusBar().showMessage(f"Now click the {c.component} component in view {other}", 10000)
            return
        pixels = [self.place_clicks[0], self.place_clicks[1]]
        self.place_clicks.clear()
        for panel in self.panels:
            panel.clear_place_marker()
        try:
            miss = c.session.place_at(c.component, c.frame, pixels)
        except (InputError, KeyError, ValueError) as exc:
            self._warn("Cannot place the model", str(exc))
            return
        quality = "good" if miss < 5 else "check that you clicked the same part in both views"
        self.statusBar().showMessage(f"Placed the {c.component} model: the rays miss by {miss:.1f} mm ({quality})",
                                     10000)
        self.last_place_miss = miss

    def _orient(self, angles) -> None:
        c = self.controller
        try:
            c.session.orient(c.component, c.frame, angles)
        except (InputError, KeyError) as exc:
            self._warn("Cannot orient the model", str(exc))
