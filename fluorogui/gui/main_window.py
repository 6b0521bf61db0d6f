"""The main window: two image panels, the 3D fluoroscope, docks, menus and toolbar.

Thin by design: the project lives in the workflow's ``Session`` (``controller.session``);
every change goes through it (undoable, announced by the ``SessionController``'s
signals); long work runs the session's jobs in ``TaskRunner``. The window's panels,
presenters, actions, menus and toolbar are declared as data in ``gui.layout``
(``WINDOW``); this module builds them in order - the image panels, the docks, the actions,
the presenters (each given what it needs), the menus and the toolbar - and keeps the
window's own concerns: its title, its layout on screen and in the settings, autosave,
dropped files and closing. Built, the parts are ``window.widgets`` / ``window.docks`` /
``window.presenters`` by key and ``window.actions_by_id`` by id; the built-in ones also
go by the names scripts, benchmarks and the guided tour use (``window.matcher``,
``window.files`` ...).
"""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from PySide6.QtCore import QByteArray, QDataStream, QSettings, Qt, QTimer, Signal
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QLabel, QMainWindow, QSplitter, QWidget

from fluorogui.gui import theme
from fluorogui.gui.controller import SessionController
from fluorogui.gui.layout.build import build_actions, build_docks, build_menus, build_toolbar, menu_order
from fluorogui.gui.layout.specs import Context, Parts, WindowLayout
from fluorogui.gui.layout.window import WINDOW
from fluorogui.gui.notices import Notices
from fluorogui.gui.panels.image_panel import ImagePanel
from fluorogui.gui.session_view import COMPONENT_COLOURS
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
                 parent: QWidget | None = None, *, layout: WindowLayout = WINDOW) -> None:
        """``layout``: what the window is built from (``gui.layout.window.WINDOW``, or a
        variant of it with more panels or actions)."""
        super().__init__(parent)
        self.settings = settings or QSettings("fluorogui", "fluorogui")
        self.controller = SessionController(self)
        self.runner = TaskRunner(self)
        self.notices = Notices(self)
        # what the actions' enabled-when read; it follows the runner before any presenter does
        self.context = Context()
        self.runner.running_changed.connect(lambda running: self.context.set(running=running))
        self.setWindowIcon(theme.icon("app"))
        self.setAcceptDrops(True)
        self.setDockNestingEnabled(True)
        self._build_image_panels()
        self.cursor_label = QLabel("")
        self.frame_label = QLabel("")
        parts = Parts(window=self, controller=self.controller, runner=self.runner, settings=self.settings,
                      notices=self.notices, context=self.context, panels=self.panels, with_3d=with_3d,
                      status_labels=SimpleNamespace(cursor=self.cursor_label, frame=self.frame_label))
        self.widgets, self.presenters = parts.widgets, parts.presenters
        self.docks = build_docks(self, layout.panels, parts)
        actions = layout.all_actions()
        self.actions_by_id = parts.actions = build_actions(self, actions, self.presenters, self.context)
        for spec in layout.presenters:
            setattr(self.presenters, spec.key, spec.make(parts))
        for spec in layout.panels:
            if spec.presenter is not None and spec.key in self.docks:
                setattr(self.presenters, spec.key, spec.presenter(parts, getattr(self.widgets, spec.key)))
        self._name_parts()
        toggles = [self.docks[key].toggleViewAction() for key in menu_order(layout.panels, self.docks)]
        self.menus = build_menus(self, layout.menus, actions, self.actions_by_id, presenters=self.presenters,
                                 panel_toggles=layout.panel_toggles, toggles=toggles)
        self.toolbar = build_toolbar(self, *layout.toolbar, actions, layout.toolbar_widgets, self.actions_by_id,
                                     self.presenters)
        self._build_status_bar()
        c = self.controller
        c.dirty_changed.connect(lambda dirty: self.setWindowModified(dirty))
        c.path_changed.connect(lambda _p: self.refresh_title())
        c.project_replaced.connect(self.refresh_title)
        self.autosave_timer = QTimer(self)
        self.autosave_timer.setInterval(int(self.settings.value("autosave_ms", AUTOSAVE_MS)))
        self.autosave_timer.timeout.connect(self.autosave)
        self.autosave_timer.start()
        self._restore_layout()
        self.focus_frame = theme.install_focus_frame(self)
        self.refresh_title()
        self.pose_editor.set_component(None)

    # -- construction ----------------------------------------------------------------------
    def _build_image_panels(self) -> None:
        self.panels = [ImagePanel(i) for i in range(2)]
        splitter = QSplitter(Qt.Orientation.Horizontal)
        for panel in self.panels:
            panel.edit_sink = self.controller.apply_edit
            for name, colour in COMPONENT_COLOURS.items():
                panel.set_component_colour(name, colour)
            panel.placeholder = NO_SESSION_HINT
            splitter.addWidget(panel)
        self.setCentralWidget(splitter)

    def _name_parts(self) -> None:
        """The built-in parts under the names scripts, benchmarks, the guided tour and the
        tests use (a new panel needs none: ``widgets.<key>``, ``docks[key]``)."""
        w, d, p = self.widgets, self.docks, self.presenters
        self.scene_widget = getattr(w, "scene", None)
        self.matcher, self.pose_editor, self.tree, self.knee_panel = w.matcher, w.pose, w.session, w.kinematics
        self.timeline, self.timeline_legend = w.frames.timeline, w.frames.legend
        self.scene_dock, self.matcher_dock, self.pose_dock = d.get("scene"), d["matcher"], d["pose"]
        self.session_dock, self.knee_dock, self.timeline_dock = d["session"], d["kinematics"], d["frames"]
        self.files, self.knee, self.edit, self.display, self.model = p.files, p.knee, p.edit, p.display, p.model
        self.missing, self.session_view, self.tasks, self.review, self.help = (
            p.missing, p.session_view, p.tasks, p.review, p.help)

    def _build_status_bar(self) -> None:
        self.statusBar().addWidget(self.edit.tool_label, 1)
        self.statusBar().addPermanentWidget(self.cursor_label)
        self.statusBar().addPermanentWidget(self.frame_label)

    # -- settings and layout ---------------------------------------------------------------
    def _restore_layout(self) -> None:
        geometry = self.settings.value("window/geometry")
        state = self.settings.value("window/state")
        if geometry is not None:
            self.restoreGeometry(geometry)
        self.fit_to_screen(first=geometry is None, saved=saved_size(geometry))
        if state is not None:
            self.restoreState(state)
        elif "scene" in self.docks and "matcher" in self.docks:
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
        self.resizeDocks([self.docks["scene"], self.docks["matcher"]], [int(height * 0.4), int(height * 0.6)],
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

    @property
    def last_error(self) -> str:
        """The text of the last warning or error shown (``Notices.last_error``)."""
        return self.notices.last_error

    def warn(self, title: str, message: str) -> None:
        """A warning dialog; its text stays in the status bar and in ``last_error``."""
        self.notices.warn(title, message)

    def ask(self, title: str, question: str) -> bool:
        """A yes / no question (No is the default): True for Yes."""
        return self.notices.ask(title, question)

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
        self.presenters.kinematics.close()  # its contact computation
        self._save_layout()
        self.files.recovery.discard()
        self.controller.close()
        self.edit.history.detach()
        if self.scene_widget is not None:
            self.scene_widget.close()
        event.accept()
