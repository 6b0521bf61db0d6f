"""The main window's panels (its docks) and presenters, declared once, each built with what
it needs from the window's ``Parts``.

``PRESENTERS`` are built first, in this order (where two follow one signal the order is
theirs: the end of a task enables Match before Accept is judged), then each panel's
presenter in the order of ``PANELS``. A presenter's key is its name for the actions
(``p.files``) and for the window (``window.presenters.files``); a panel's key names its
widget (``window.widgets.matcher``), its dock (``window.docks["matcher"]``) and its
presenter. The docks' object names are what saved window layouts restore: never change
them.
"""
from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QDockWidget, QTreeWidget

from fluorogui.gui import theme
from fluorogui.gui.actions.edit import TOOLS, EditActions
from fluorogui.gui.actions.files import SessionFiles
from fluorogui.gui.actions.frames import FramesPresenter
from fluorogui.gui.actions.help import HelpActions
from fluorogui.gui.actions.kinematics import KinematicsPresenter
from fluorogui.gui.actions.knee import KneeActions
from fluorogui.gui.actions.model import ModelActions
from fluorogui.gui.actions.pose import PoseEdits
from fluorogui.gui.actions.review import ReviewActions
from fluorogui.gui.actions.session_tree import SessionTree
from fluorogui.gui.actions.tasks import MatchControl
from fluorogui.gui.actions.view import ViewActions
from fluorogui.gui.dialogs.missing_files import MissingFiles
from fluorogui.gui.layout.specs import PanelSpec, Parts, PresenterSpec
from fluorogui.gui.panels.knee_panel import KneePanel
from fluorogui.gui.panels.matcher_panel import MatcherPanel
from fluorogui.gui.panels.pose_editor import PoseEditor
from fluorogui.gui.panels.timeline import FramesBar
from fluorogui.gui.session_view import SessionView

RIGHT, BOTTOM = Qt.DockWidgetArea.RightDockWidgetArea, Qt.DockWidgetArea.BottomDockWidgetArea


def _scene(parts: Parts):
    """The 3D scene, when the window has one (rays on demand: they hide the models)."""
    if not parts.with_3d:
        return None
    from fluorogui.gui.scene.scene_widget import Scene3DWidget

    widget = Scene3DWidget(parts.window)
    widget.rays_button.setChecked(False)
    return widget


def _tree(_parts: Parts) -> QTreeWidget:
    tree = QTreeWidget()
    tree.setHeaderHidden(True)
    return tree


PANELS = (
    PanelSpec("scene", "3D scene", "sceneDock", RIGHT, _scene),  # drawn by the session view
    PanelSpec("matcher", "Matcher", "matcherDock", RIGHT, lambda parts: MatcherPanel(), raised=True, scroll=True),
    PanelSpec("pose", "Pose", "poseDock", RIGHT, lambda parts: PoseEditor(),
              lambda parts, editor: PoseEdits(parts.controller, editor, getattr(parts.widgets, "scene", None)),
              tab_with="matcher", scroll=True),
    PanelSpec("session", "Session", "sessionDock", RIGHT, _tree,
              lambda parts, tree: SessionTree(parts.controller, tree), tab_with="pose"),
    PanelSpec("kinematics", "Kinematics", "kneeDock", RIGHT, lambda parts: KneePanel(),
              lambda parts, panel: KinematicsPresenter(parts.controller, panel, parts.notices,
                                                       export_folder=parts.presenters.knee._export_folder,
                                                       scene=getattr(parts.widgets, "scene", None),
                                                       points_action=parts.actions["view.contact_points"]),
              tab_with="session"),
    PanelSpec("frames", "Frames", "timelineDock", BOTTOM, lambda parts: FramesBar(),
              lambda parts, bar: FramesPresenter(parts.controller, bar.timeline),
              features=QDockWidget.DockWidgetFeature.DockWidgetMovable),
)


# -- the presenters that are not one panel's -----------------------------------------------------------
def _files(parts: Parts) -> SessionFiles:
    return SessionFiles(parts.controller, parts.runner, parts.settings, parts.notices,
                        close=parts.window.close, refresh_title=parts.window.refresh_title)


def _edit(parts: Parts) -> EditActions:
    return EditActions(parts.controller, parts.panels, parts.widgets.matcher, parts.notices,
                       undo_action=parts.actions["edit.undo"], redo_action=parts.actions["edit.redo"],
                       tool_actions={tool: parts.actions[f"edit.tool.{tool.name.lower()}"] for tool, *_ in TOOLS})


def _display(parts: Parts) -> ViewActions:
    return ViewActions(parts.settings, parts.panels, edges_action=parts.actions["view.edges"],
                       theme_actions={name: parts.actions[f"view.theme.{name}"] for name in theme.THEMES})


def _model(parts: Parts) -> ModelActions:
    model = ModelActions(parts.controller, parts.panels, parts.notices)
    parts.presenters.edit.tool_changed.connect(model.tool_changed)  # the Place tool starts a pair of clicks
    return model


def _missing(parts: Parts) -> MissingFiles:
    return MissingFiles(parts.controller, parts.notices, default_dir=parts.presenters.files.default_save_dir)


def _session_view(parts: Parts) -> SessionView:
    w = parts.widgets
    return SessionView(parts.controller, parts.panels, getattr(w, "scene", None), w.matcher, w.pose, parts.notices,
                       labels=parts.status_labels, frame_shown=parts.window.frame_shown,
                       offer_locate=parts.presenters.missing.offer_locate, is_running=parts.runner.is_running)


def _tasks(parts: Parts) -> MatchControl:
    p = parts.presenters
    return MatchControl(parts.controller, parts.runner, parts.widgets.matcher, getattr(parts.widgets, "scene", None),
                        p.session_view, p.missing, parts.notices)


def _review(parts: Parts) -> ReviewActions:
    review = ReviewActions(parts.controller, parts.runner, parts.widgets.matcher, parts.notices, parts.context)
    parts.presenters.session_view.pose_status_shown.connect(review.refresh_accept_state)
    return review


def _help(parts: Parts) -> HelpActions:
    from fluorogui.gui.dialogs.tour import start_tour

    window = parts.window
    return HelpActions(window, window_actions=window.actions, start_tour=lambda: start_tour(window, force=True))


PRESENTERS = (
    PresenterSpec("files", _files),
    PresenterSpec("knee", lambda parts: KneeActions(parts.window)),  # export and import: still the window's
    PresenterSpec("edit", _edit),
    PresenterSpec("display", _display),
    PresenterSpec("model", _model),
    PresenterSpec("missing", _missing),
    PresenterSpec("session_view", _session_view),
    PresenterSpec("tasks", _tasks),
    PresenterSpec("review", _review),
    PresenterSpec("help", _help),
)
