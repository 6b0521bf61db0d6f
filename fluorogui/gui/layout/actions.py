"""The main window's menus, actions and toolbar, declared once.

``ACTIONS`` is in the order *Help → Keyboard shortcuts* lists them; where each is shown
is its ``places``. Each ``run`` calls a presenter by its key (``p.files`` is the window's
``SessionFiles``; the keys are those of ``gui.layout.panels``). Groups are named
"<n>_<what>" so that they sort in the order they are shown.
"""
from __future__ import annotations

from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import QLabel

from fluorogui.gui import theme
from fluorogui.gui.actions.edit import TOOLS
from fluorogui.gui.actions.pose import NUDGE_KEYS
from fluorogui.gui.layout.specs import MENUBAR, TOOLBAR, ActionSpec, MenuSpec, Place, WidgetSpec
from fluorogui.gui.panels.image_items import Tool
from fluorogui.workflow.session import ORIENTATION_PRESETS

Std = QKeySequence.StandardKey
IDLE = ("!running",)  # no task runs: nothing else may start or open meanwhile

MENUS = (
    MenuSpec("file", "&File", Place(MENUBAR, order=1)),
    MenuSpec("edit", "&Edit", Place(MENUBAR, order=2)),
    MenuSpec("view", "&View", Place(MENUBAR, order=3)),
    MenuSpec("model", "&Model", Place(MENUBAR, order=4)),
    MenuSpec("match", "M&atch", Place(MENUBAR, order=5)),
    MenuSpec("help", "&Help", Place(MENUBAR, order=6)),
    MenuSpec("file.recent", "Open &recent", Place("file", "1_open", 3), provided=lambda p: p.files.recent_menu),
    MenuSpec("view.theme", "&Theme", Place("view", "3_theme")),
    MenuSpec("model.component", "Active &component", Place("model", order=1),
             provided=lambda p: p.model.component_menu),
    MenuSpec("model.orient", "&Orientation preset", Place("model", order=3)),
)

#: where the View menu lists the panels (a check box each, in the window's order of docks)
PANEL_TOGGLES = Place("view", "2_panels")
#: the toolbar's title and object name (a saved window layout restores it by that name)
TOOLBAR_TITLE, TOOLBAR_NAME = "Main", "mainToolbar"

TOOLBAR_WIDGETS = (
    WidgetSpec("toolbar.component_label", lambda p: QLabel(" Component "), Place(TOOLBAR, "2_component", 1)),
    WidgetSpec("toolbar.component", lambda p: p.model.component_combo, Place(TOOLBAR, "2_component", 2)),
    WidgetSpec("toolbar.canny_low", lambda p: p.display.low_slider, Place(TOOLBAR, "4_images", 3)),
    WidgetSpec("toolbar.canny_high", lambda p: p.display.high_slider, Place(TOOLBAR, "4_images", 4)),
)


def _tool_places(tool: Tool, index: int) -> tuple[Place, ...]:
    places = (Place("edit", "2_tools", index), Place(TOOLBAR, "3_tools", index))
    return places + ((Place("model", order=4),) if tool == Tool.PLACE else ())


def _tool_actions() -> tuple[ActionSpec, ...]:
    return tuple(
        ActionSpec(f"edit.tool.{tool.name.lower()}", text, lambda p, t=tool: p.edit.set_tool(t), _tool_places(tool, i),
                   shortcut=key, icon=icon, tip=f"{tip} ({key})", checkable=True, checked=tool == Tool.NAVIGATE,
                   exclusive="tools")
        for i, (tool, icon, text, key, tip) in enumerate(TOOLS))


def _nudge_actions() -> tuple[ActionSpec, ...]:
    """Ctrl+arrows move the active model, Ctrl+Shift+arrows turn it (in no menu)."""
    specs = []
    for key, axis, direction in NUDGE_KEYS:
        sign, word = ("+", "plus") if direction > 0 else ("-", "minus")
        for name, shift, index in (("xyz"[axis], "", axis), (("alpha", "beta", "gamma")[axis], "Shift+", axis + 3)):
            verb = "Turn" if shift else "Move"
            specs.append(ActionSpec(f"pose.{verb.lower()}_{name}_{word}", f"{verb} {name} {sign}",
                                    lambda p, a=index, d=direction: p.pose.nudge(a, d),
                                    shortcut=f"Ctrl+{shift}{key}"))
    return tuple(specs)


def _in(menu: str, group: str = "", order: float = 0, toolbar: tuple[str, float] | None = None) -> tuple[Place, ...]:
    """Placed in ``menu`` (and on the toolbar: ``toolbar`` = (group, order))."""
    return (Place(menu, group, order),) + ((Place(TOOLBAR, *toolbar),) if toolbar else ())


ACTIONS = (
    # the File menu
    ActionSpec("file.open", "&Open…", lambda p: p.files.open_project(), _in("file", "1_open", 2, ("1_file", 1)),
               shortcut=Std.Open, icon="open", tip="Open a fluorogui project (Ctrl+O)", enabled_when=IDLE),
    ActionSpec("file.new", "&New session from images and calibration…", lambda p: p.files.import_session(),
               _in("file", "1_open", 1), shortcut=Std.New, enabled_when=IDLE),
    ActionSpec("file.demo", "Open the &demo session", lambda p: p.files.open_demo(), _in("file", "1_open", 4),
               enabled_when=IDLE),
    ActionSpec("file.save", "&Save", lambda p: p.files.save(), _in("file", "2_save", 1, ("1_file", 2)),
               shortcut=Std.Save, icon="save", tip="Save the session (Ctrl+S)"),
    ActionSpec("file.save_as", "Save &as…", lambda p: p.files.save_as(), _in("file", "2_save", 2),
               shortcut=Std.SaveAs),
    ActionSpec("file.calibrate", "&Calibrate fluoroscope (plate, beads)…", lambda p: p.files.calibrate_fluoroscope(),
               _in("file", "3_calibrate")),
    ActionSpec("file.quit", "&Quit", lambda p: p.files.quit(), _in("file", "5_quit"), shortcut=Std.Quit),
    ActionSpec("file.export", "&Export results…", lambda p: p.knee.export_results(), _in("file", "4_exchange", 1),
               shortcut="Ctrl+Shift+E", tip="Write poses, kinematics, Autoscoper .tra, JointTrack .jts or the figure"),
    ActionSpec("file.import_poses", "&Import poses…", lambda p: p.knee.import_poses_file(),
               _in("file", "4_exchange", 2), tip="Read poses from our CSV, Autoscoper .tra or JointTrack .jts"),
    # the Edit menu: Undo and Redo follow the session's history (actions.undo connects them)
    ActionSpec("edit.undo", "&Undo", None, _in("edit", "1_undo", 1), shortcut=("Ctrl+Z", Std.Undo)),
    ActionSpec("edit.redo", "&Redo", None, _in("edit", "1_undo", 2), shortcut=("Ctrl+Shift+Z", "Ctrl+Y", Std.Redo)),
    *_tool_actions(),
    ActionSpec("edit.clear_outline", "Clear outline of the active component", lambda p: p.edit.clear_outlines(),
               _in("edit", "3_outline")),
    # the View menu
    ActionSpec("view.fit", "&Fit images", lambda p: p.display.fit_images(), _in("view", "1_images", 1, ("4_images", 1)),
               shortcut="F", icon="fit", tip="Fit both images to their panels"),
    ActionSpec("view.edges", "Show &edges", lambda p: p.display.toggle_edges(),
               _in("view", "1_images", 2, ("4_images", 2)), shortcut="Ctrl+E", icon="edges",
               tip="Show Canny edges (thresholds on the toolbar)", checkable=True),
    ActionSpec("view.contact_points", "Condyle &contact points", lambda p: p.kinematics.toggle_contact_points(),
               _in("view", "2_scene", 1), checkable=True,
               tip="Show each femoral condyle's lowest point on the tray in the 3D scene, for the frame on screen "
                   "(medial magenta, lateral yellow)"),
    # the active model's pose from the keyboard
    *_nudge_actions(),
    # the Match menu (and Find in the Model menu)
    ActionSpec("match.run", "&Match active component", lambda p: p.tasks.run_match(),
               _in("match", "1_tasks", 1, ("5_match", 1)), shortcut="F5", icon="match",
               tip="Match the active component in this frame (F5)", enabled_when=IDLE),
    ActionSpec("match.run_both", "Match &both components", lambda p: p.tasks.match_both(),
               _in("match", "1_tasks", 2, ("5_match", 2)), shortcut="Ctrl+F5", icon="match_both",
               tip="Match every component in this frame (Ctrl+F5)", enabled_when=IDLE),
    ActionSpec("match.cancel", "&Cancel", lambda p: p.tasks.cancel(), _in("match", "1_tasks", 3, ("5_match", 4)),
               shortcut="Esc", icon="cancel", tip="Stop the running task (Esc)", enabled_when=("running",)),
    ActionSpec("match.track", "&Track following frames", lambda p: p.tasks.track_frames(), _in("match", "1_tasks", 4),
               shortcut="Shift+F5", tip="Track the active component through the following frames (Shift+F5)",
               enabled_when=IDLE),
    ActionSpec("match.track_both", "Track &both through following frames", lambda p: p.tasks.track_both(),
               _in("match", "1_tasks", 5, ("5_match", 3)), shortcut="Ctrl+Shift+F5", icon="track_both",
               tip="Track every component through the following frames (Ctrl+Shift+F5)", enabled_when=IDLE),
    ActionSpec("model.find", "&Find implants automatically", lambda p: p.tasks.find_implants(), _in("model", order=5),
               shortcut="Ctrl+F", tip="Locate every component in this frame's images (Ctrl+F)", enabled_when=IDLE),
    # deciding on poses and moving through the frames
    ActionSpec("match.accept", "&Accept pose", lambda p: p.review.accept_pose(),
               _in("match", "1_tasks", 6, ("5_match", 5)), shortcut="Ctrl+Return", icon="accept",
               tip="Accept the active component's pose in this frame (Ctrl+Return)",
               enabled_when=("!running", "pose_acceptable", "!pose_accepted")),
    ActionSpec("match.unaccept", "&Un-accept pose", lambda p: p.review.unaccept_pose(), _in("match", "1_tasks", 7),
               shortcut="Ctrl+Shift+Return",
               tip="Take back the acceptance of the active component's pose (Ctrl+Shift+Return)",
               enabled_when=("!running", "pose_accepted")),
    ActionSpec("match.next_frame", "&Next frame", lambda p: p.review.step_frame(1), _in("match", "2_frames", 1),
               shortcut="PgDown"),
    ActionSpec("match.previous_frame", "&Previous frame", lambda p: p.review.step_frame(-1),
               _in("match", "2_frames", 2), shortcut="PgUp"),
    ActionSpec("match.first_frame", "&First frame", lambda p: p.review.go_to_end(first=True),
               _in("match", "2_frames", 3), shortcut="Home"),
    ActionSpec("match.last_frame", "&Last frame", lambda p: p.review.go_to_end(first=False),
               _in("match", "2_frames", 4), shortcut="End"),
    ActionSpec("model.next_component", "Next &component", lambda p: p.review.cycle_component(), _in("model", order=2),
               shortcut="K", tip="Make the next component the active one (K)"),
    # the Help menu
    ActionSpec("help.quick_start", "&Quick start", lambda p: p.help.show_quick_start(), _in("help", "1_guides", 1),
               tip="How to outline, place, match, track and export"),
    ActionSpec("help.shortcuts", "&Keyboard shortcuts", lambda p: p.help.show_shortcuts(),
               _in("help", "1_guides", 2), shortcut="F1", tip="Every keyboard shortcut and mouse gesture (F1)"),
    ActionSpec("help.tour", "Guided &tour", lambda p: p.help.show_tour(), _in("help", "1_guides", 3),
               tip="A one-minute tour of the window"),
    ActionSpec("help.about", "&About fluorogui", lambda p: p.help.show_about(), _in("help", "2_about"),
               tip="Version, log file and data folder"),
    # the submenus: the themes and the orientation presets
    *(ActionSpec(f"view.theme.{name}", name.capitalize(), lambda p, n=name: p.display.set_theme(n),
                 _in("view.theme", order=i), checkable=True, exclusive="theme")
      for i, name in enumerate(theme.THEMES)),
    *(ActionSpec(f"model.orient.{i}", text, lambda p, a=angles: p.model.orient(a), _in("model.orient", order=i))
      for i, (text, angles) in enumerate(ORIENTATION_PRESETS)),
)
