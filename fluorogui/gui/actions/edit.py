"""The Edit menu of the main window: Undo / Redo (bound to the session's history) with
the status bar saying what was undone, the image panels' editing tools with the
status-bar hint of the current one, and clearing the active component's outlines (one
undoable step). The actions are declared in ``gui.layout.actions`` (the tools from
``TOOLS``); ``EditActions`` is given the ones it keeps in step."""
from __future__ import annotations

from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QLabel

from fluorogui.gui.actions.undo import UndoActions
from fluorogui.gui.notices import Notices
from fluorogui.gui.panels.image_items import Tool
from fluorogui.gui.panels.matcher_panel import MatcherPanel

TOOLS = (  # tool, icon, text, key, what it does
    (Tool.NAVIGATE, "navigate", "Navigate", "N",
     "Pan and zoom (wheel zooms at the cursor, right-drag sets window/level)"),
    (Tool.PICK_CONTOUR, "pick", "Pick contour", "P",
     "Click an edge contour to take it as the outline (Shift adds one)"),
    (Tool.MOVE, "move", "Move point", "M", "Drag an outline point"),
    (Tool.INSERT, "insert", "Insert point", "I", "Click to insert a point into the nearest segment"),
    (Tool.DELETE, "delete", "Delete point", "D", "Click to delete the nearest point"),
    (Tool.ERASE, "erase", "Erase", "E", "Brush away edges and outline points"),
    (Tool.LASSO, "lasso", "Lasso delete", "L", "Draw around outline points to delete them"),
    (Tool.CLOSE_GAP, "close_gap", "Close gap", "G", "Click two outline points to bridge the gap between them"),
    (Tool.PLACE, "place", "Place model", "C", "Click the component in view 1 and view 2 to place the model there"),
)


class EditActions(QObject):
    """Undo / Redo, the editing tools and *Clear outline* of a main window."""

    tool_changed = Signal(object)  # the Tool now in use

    def __init__(self, controller, panels: list, matcher: MatcherPanel, notices: Notices, *,
                 undo_action: QAction, redo_action: QAction, tool_actions: dict[Tool, QAction]) -> None:
        """``tool_actions``: the action of each tool (checkable, one at a time)."""
        super().__init__(notices.parent_widget)
        self.controller = controller
        self.panels = panels
        self.matcher = matcher
        self.notices = notices
        self.history = UndoActions(self.controller.session.history, undo_action, redo_action)
        self.undo_action, self.redo_action = undo_action, redo_action
        self.history.stepped.connect(self._stepped)
        for panel in panels:
            panel.nothing_to_edit.connect(lambda tool, name, view=panel.view_index: self._no_outline(tool, name, view))
        self.tool_label = QLabel("")  # what the current tool does, always in view
        self.tool_label.setObjectName("toolHint")
        self.tool_actions = tool_actions
        self._show_tool_hint(Tool.NAVIGATE)

    def _stepped(self, event: str, text: str) -> None:
        """After an undo or redo the status bar says what changed: a task's message there
        ("femoral matched … Ctrl+Return accepts") may no longer hold, nor the matcher's
        account of the last task, which is put away (its pose lines show the state now)."""
        done, other = ("Undone", "Ctrl+Shift+Z redoes it") if event == "undo" else ("Redone", "Ctrl+Z undoes it")
        self.notices.status(f"{done}: {text or 'the last step'} ({other})", 10000)
        self.matcher.show_summary("")

    def _no_outline(self, tool: Tool, component: str, view: int) -> None:
        """An outline tool used where there is no outline to edit: what to do first."""
        text = next(t for tl, _i, t, _k, _h in TOOLS if tl == tool)
        self.notices.status(
            f"{text}: there is no {component} outline in view {view + 1} yet. Match (F5) outlines it from "
            "the image, or Pick contour (P) takes an edge as its outline.", 10000)

    def _show_tool_hint(self, tool: Tool) -> None:
        text, key, tip = next((t, k, h) for tl, _i, t, k, h in TOOLS if tl == tool)
        self.tool_label.setText(f"{text} ({key}): {tip}")

    def set_tool(self, tool: Tool) -> None:
        for panel in self.panels:
            panel.set_tool(tool)
        self.tool_actions[tool].setChecked(True)
        self._show_tool_hint(tool)
        self.tool_changed.emit(tool)

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
