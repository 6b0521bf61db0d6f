"""The main window: two image panels, the 3D fluoroscope, docks, menus and toolbar.

Thin by design: the project lives in the workflow's ``Session`` (``controller.session``);
every change goes through it (undoable, announced by the ``SessionController``'s
signals); long work runs the session's jobs in ``TaskRunner``. This module builds the
window and puts its parts together. What the window does is in objects it owns, each
with its own actions (``gui.actions``): ``files`` (open, save, import, autosave),
``edit`` (undo bound to the session's history, the editing tools), ``display`` (the View
menu), ``model`` (the active component, placing), ``tasks`` (match, track, find),
``review`` (frames, accept), ``knee`` (export, kinematics) and ``help``; ``session_view``
shows the session and ``missing`` asks for missing model files.
"""
from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QByteArray, QDataStream, QSettings, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QGuiApplication, QKeySequence
from PySide6.QtWidgets import (
    QDockWidget,
    QFrame,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QMessageBox,
    QScrollArea,
    QSplitter,
    QTreeWidget,
    QWidget,
)

from fluorogui.gui import theme
from fluorogui.gui.actions.edit import TOOLS, EditActions
from fluorogui.gui.actions.files import SessionFiles
from fluorogui.gui.actions.help import HelpActions
from fluorogui.gui.actions.knee import KneeActions
from fluorogui.gui.actions.model import ModelActions
from fluorogui.gui.actions.review import ReviewActions
from fluorogui.gui.actions.tasks import MatchControl
from fluorogui.gui.actions.view import ViewActions
from fluorogui.gui.controller import SessionController
from fluorogui.gui.dialogs.missing_files import MissingFiles
from fluorogui.gui.panels.image_items import Tool
from fluorogui.gui.panels.image_panel import ImagePanel
from fluorogui.gui.panels.knee_panel import KneePanel
from fluorogui.gui.panels.matcher_panel import MatcherPanel
from fluorogui.gui.panels.pose_editor import PoseEditor
from fluorogui.gui.panels.timeline import Timeline, TimelineLegend
from fluorogui.gui.session_view import COMPONENT_COLOURS, SessionView
from fluorogui.gui.worker import TaskRunner

AUTOSAVE_MS = 3 * 60 * 1000
#: the largest first window; a smaller screen (a 1280×720 or 1366×768 laptop) gets all it has
FIRST_SIZE = (1600, 1000)
#: room (px) left for the window manager's title bar and borders, which Qt's size excludes
FRAME_ALLOWANCE = (16, 40)
#: the first field of QWidget.saveGeometry's data
GEOMETRY_MAGIC = 0x1D9D0CB
NO_SESSION_HINT = ("No session open.\nFile → Open… (Ctrl+O) opens a project,\nFile → New session (Ctrl+N) "
                   "imports images,\nFile → Open the demo session to try it out.")


def saved_size(geometry) -> tuple[int, int] | None:
    """The window size (its normal geometry, without the frame) stored in
    ``QWidget.saveGeometry``'s data; None when it is not such data."""
    if not isinstance(geometry, QByteArray) or geometry.size() < 40:
        return None
    stream = QDataStream(geometry)
    stream.setVersion(QDataStream.Version.Qt_4_0)  # the version saveGeometry writes with
    if stream.readUInt32() != GEOMETRY_MAGIC:
        return None
    stream.readUInt16(), stream.readUInt16()  # format version
    _frame = [stream.readInt32() for _ in range(4)]
    left, top, right, bottom = (stream.readInt32() for _ in range(4))  # normal geometry, inclusive
    width, height = right - left + 1, bottom - top + 1
    return (width, height) if width > 0 and height > 0 else None


class MainWindow(QMainWindow):
    """The fluorogui main window."""

    frame_shown = Signal(int)  # frame number, emitted after its images and overlays are on screen

    def __init__(self, settings: QSettings | None = None, with_3d: bool = True,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.settings = settings or QSettings("fluorogui", "fluorogui")
        self.controller = SessionController(self)
        self.runner = TaskRunner(self)
        self.last_error = ""
        self.setWindowIcon(theme.icon("app"))
        self.setAcceptDrops(True)
        self.setDockNestingEnabled(True)
        self._build_widgets(with_3d)
        self._build_docks()
        self.cursor_label = QLabel("")
        self.frame_label = QLabel("")

        # what the window does, each part with its own actions; the order matters only where
        # two parts follow one signal (the task's end enables Match before Accept is judged)
        self.files = SessionFiles(self)
        self.knee = KneeActions(self)
        self.edit = EditActions(self)
        self.display = ViewActions(self)
        self.model = ModelActions(self)
        self.tasks = MatchControl(self)
        self.review = ReviewActions(self)
        self.help = HelpActions(self)
        self.missing = MissingFiles(self)
        self.session_view = SessionView(self)

        self._build_menus()
        self._build_toolbar()
        self._build_status_bar()
        self._connect()
        self.autosave_timer = QTimer(self)
        self.autosave_timer.setInterval(int(self.settings.value("autosave_ms", AUTOSAVE_MS)))
        self.autosave_timer.timeout.connect(self.autosave)
        self.autosave_timer.start()
        self._restore_layout()
        self.focus_frame = theme.install_focus_frame(self)
        self.refresh_title()
        self.pose_editor.set_component(None)

    # -- construction ----------------------------------------------------------------------
    def _build_widgets(self, with_3d: bool) -> None:
        self.panels = [ImagePanel(i) for i in range(2)]
        splitter = QSplitter(Qt.Orientation.Horizontal)
        for panel in self.panels:
            panel.edit_sink = self.controller.apply_edit
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
        self.pose_editor = PoseEditor()
        self.matcher = MatcherPanel()
        self.timeline = Timeline()
        self.knee_panel = KneePanel()
        self.tree = QTreeWidget()
        self.tree.setHeaderHidden(True)

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
        self.knee_dock = self._dock("Kinematics", self.knee_panel, right, "kneeDock")
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

    def add_action(self, text: str, slot, shortcut=None, icon: str | None = None, tip: str = "") -> QAction:
        """An action of this window (its shortcut works anywhere in it, and F1 lists it)."""
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

    def _build_menus(self) -> None:
        files, edit, display, model = self.files, self.edit, self.display, self.model
        tasks, review, knee, help_ = self.tasks, self.review, self.knee, self.help
        menu = self.menuBar()
        file_menu = menu.addMenu("&File")
        file_menu.addAction(files.new_action)
        file_menu.addAction(files.open_action)
        file_menu.addMenu(files.recent_menu)
        file_menu.addAction(files.demo_action)
        file_menu.addSeparator()
        file_menu.addAction(files.save_action)
        file_menu.addAction(files.save_as_action)
        file_menu.addSeparator()
        file_menu.addAction(files.calibrate_action)
        file_menu.addSeparator()
        file_menu.addAction(knee.export_action)
        file_menu.addAction(knee.import_poses_action)
        file_menu.addSeparator()
        file_menu.addAction(files.quit_action)

        edit_menu = menu.addMenu("&Edit")
        edit_menu.addAction(edit.undo_action)
        edit_menu.addAction(edit.redo_action)
        edit_menu.addSeparator()
        for tool, *_ in TOOLS:
            edit_menu.addAction(edit.tool_actions[tool])
        edit_menu.addSeparator()
        edit_menu.addAction(edit.clear_outline_action)

        view_menu = menu.addMenu("&View")
        view_menu.addAction(display.fit_action)
        view_menu.addAction(display.edges_action)
        view_menu.addSeparator()
        for dock in self.findChildren(QDockWidget):
            view_menu.addAction(dock.toggleViewAction())
        view_menu.addSeparator()
        theme_menu = view_menu.addMenu("&Theme")
        for action in display.theme_actions:
            theme_menu.addAction(action)

        model_menu = menu.addMenu("&Model")
        model_menu.addMenu(model.component_menu)
        model_menu.addAction(review.next_component_action)
        model_menu.addMenu(model.orient_menu)
        model_menu.addAction(edit.tool_actions[Tool.PLACE])
        model_menu.addAction(tasks.find_action)

        match_menu = menu.addMenu("M&atch")
        for action in (tasks.run_action, tasks.run_both_action, tasks.cancel_action, tasks.track_action,
                       tasks.track_both_action, review.accept_action, review.unaccept_action):
            match_menu.addAction(action)
        match_menu.addSeparator()
        for action in (review.next_action, review.prev_action, review.first_action, review.last_action):
            match_menu.addAction(action)

        help_menu = menu.addMenu("&Help")
        for action in (help_.quick_start_action, help_.shortcuts_action, help_.tour_action):
            help_menu.addAction(action)
        help_menu.addSeparator()
        help_menu.addAction(help_.about_action)

    def _build_toolbar(self) -> None:
        files, edit, display, tasks = self.files, self.edit, self.display, self.tasks
        bar = self.addToolBar("Main")
        bar.setObjectName("mainToolbar")
        bar.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonIconOnly)
        bar.addAction(files.open_action)
        bar.addAction(files.save_action)
        bar.addSeparator()
        bar.addWidget(QLabel(" Component "))
        bar.addWidget(self.model.component_combo)
        bar.addSeparator()
        for tool, *_ in TOOLS:
            bar.addAction(edit.tool_actions[tool])
        bar.addSeparator()
        bar.addAction(display.fit_action)
        bar.addAction(display.edges_action)
        bar.addWidget(display.low_slider)
        bar.addWidget(display.high_slider)
        bar.addSeparator()
        for action in (tasks.run_action, tasks.run_both_action, tasks.track_both_action, tasks.cancel_action,
                       self.review.accept_action):
            bar.addAction(action)

    def _build_status_bar(self) -> None:
        self.statusBar().addWidget(self.edit.tool_label, 1)
        self.statusBar().addPermanentWidget(self.cursor_label)
        self.statusBar().addPermanentWidget(self.frame_label)

    def _connect(self) -> None:
        """What joins the parts: each part wires its own actions and the signals it follows."""
        c = self.controller
        c.dirty_changed.connect(lambda dirty: self.setWindowModified(dirty))
        c.path_changed.connect(lambda _p: self.refresh_title())
        self.edit.tool_changed.connect(self.model.tool_changed)
        self.pose_editor.pose_edited.connect(
            lambda pose: c.session.set_pose(c.component, c.frame, pose, text="Edit pose", mergeable=True))
        if self.scene_widget is not None:
            self.scene_widget.pose_dragged.connect(
                lambda name, pose: c.session.set_pose(name, c.frame, pose, text="Drag model", mergeable=True))
        self.timeline.frame_selected.connect(c.set_frame)

    # -- settings and layout ---------------------------------------------------------------
    def _restore_layout(self) -> None:
        geometry = self.settings.value("window/geometry")
        state = self.settings.value("window/state")
        if geometry is not None:
            self.restoreGeometry(geometry)
        self.fit_to_screen(first=geometry is None, saved=saved_size(geometry))
        if state is not None:
            self.restoreState(state)
        elif self.scene_widget is not None:
            QTimer.singleShot(0, self._share_right_column)

    def fit_to_screen(self, first: bool = False, saved: tuple[int, int] | None = None) -> None:
        """Keep the window on the screen's available area (less the taskbar): on the first
        start ``FIRST_SIZE`` or as much as the screen has (a 1280×720 or 1366×768 laptop),
        centred; a geometry saved on a larger monitor is shrunk to fit. ``saved``: the size
        of the restored geometry as it was saved; larger than this screen, the window takes
        all the screen has (Qt's restoreGeometry makes it two thirds of the screen, too
        narrow for the toolbar)."""
        screen = self.screen() or QGuiApplication.primaryScreen()
        if screen is None:
            if first:
                self.resize(*FIRST_SIZE)
            return
        area = screen.availableGeometry()
        most_w, most_h = area.width() - FRAME_ALLOWANCE[0], area.height() - FRAME_ALLOWANCE[1]
        if first:
            width, height = min(FIRST_SIZE[0], most_w), min(FIRST_SIZE[1], most_h)
        else:
            if self.isMaximized() or self.isFullScreen():
                return
            width, height = min(self.width(), most_w), min(self.height(), most_h)
            if saved is not None and (saved[0] > most_w or saved[1] > most_h):
                width, height = min(saved[0], most_w), min(saved[1], most_h)
            if (width, height) == (self.width(), self.height()) and area.contains(self.frameGeometry()):
                return
        self.resize(width, height)
        self.move(area.x() + max(0, (area.width() - width - FRAME_ALLOWANCE[0]) // 2),
                  area.y() + max(0, (area.height() - height - FRAME_ALLOWANCE[1]) // 2))

    def _share_right_column(self) -> None:
        """First start: the 3D scene takes 40 % of the right column, the tabs the rest."""
        height = max(self.height() - 160, 300)
        self.resizeDocks([self.scene_dock, self.matcher_dock], [int(height * 0.4), int(height * 0.6)],
                         Qt.Orientation.Vertical)

    def _save_layout(self) -> None:
        self.settings.setValue("window/geometry", self.saveGeometry())
        self.settings.setValue("window/state", self.saveState())
        self.display.save_settings()

    # -- what every part uses --------------------------------------------------------------
    @property
    def session(self):
        return self.controller.session

    def refresh_title(self) -> None:
        path = self.controller.path
        name = path.name if path else "untitled"
        if self.controller.project.settings.get("demo"):
            name += " (demo)"
        if self.controller.read_only:
            name += " (read-only)"
        self.setWindowTitle(f"{name}[*] — fluorogui")
        self.setWindowModified(self.controller.dirty)

    def warn(self, title: str, message: str) -> None:
        """A warning dialog; its text stays in the status bar and in ``last_error``."""
        self.last_error = message
        self.statusBar().showMessage(message, 10000)
        QMessageBox.warning(self, title, message)

    def ask(self, title: str, question: str) -> bool:
        """A yes / no question (No is the default): True for Yes."""
        answer = QMessageBox.question(self, title, question,
                                      QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
                                      QMessageBox.StandardButton.No)
        return answer == QMessageBox.StandardButton.Yes

    # -- what the app, the crash handler and scripts call ------------------------------------
    def open_project(self, path=None, ask: bool = True, quiet_read_only: bool = False) -> bool:
        return self.files.open_project(path, ask, quiet_read_only)

    def open_demo(self, ask: bool = True) -> bool:
        return self.files.open_demo(ask)

    def open_paths(self, paths) -> None:
        self.files.open_paths(paths)

    def offer_recovery(self) -> bool:
        return self.files.offer_recovery()

    def autosave(self) -> bool:
        return self.files.autosave()

    def recovery_path(self):
        return self.files.recovery_path()

    def fit_images(self) -> None:
        self.display.fit_images()

    def run_match(self, components=None) -> bool:
        return self.tasks.run_match(components)

    def match_both(self) -> bool:
        return self.tasks.match_both()

    def track_both(self) -> bool:
        return self.tasks.track_both()

    def find_implants(self) -> bool:
        return self.tasks.find_implants()

    # -- Qt events -------------------------------------------------------------------------
    def dragEnterEvent(self, event) -> None:  # noqa: N802 (Qt override)
        if event.mimeData().hasUrls():
            event.acceptProposedAction()

    def dropEvent(self, event) -> None:  # noqa: N802 (Qt override)
        paths = [Path(u.toLocalFile()) for u in event.mimeData().urls() if u.isLocalFile()]
        event.acceptProposedAction()
        self.files.open_paths(paths)

    def closeEvent(self, event) -> None:  # noqa: N802 (Qt override)
        if not self.files.maybe_save():
            event.ignore()
            return
        if self.runner.is_running():
            self.runner.cancel()
            self.runner.wait(5000)
        self._save_layout()
        self.files.recovery.discard()
        self.controller.close()
        self.edit.history.detach()
        if self.scene_widget is not None:
            self.scene_widget.close()
        event.accept()
