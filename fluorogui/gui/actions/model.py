"""The Model menu of the main window: the active component (menu and toolbar list), the
orientation presets and placing a model by a click in each view. The pose itself is
computed by the session (``place_at``, ``orient``). The menu's actions are declared in
``gui.layout.actions``; the active component's menu and list change with the session and
are this presenter's own."""
from __future__ import annotations

from PySide6.QtCore import QObject
from PySide6.QtGui import QAction, QActionGroup
from PySide6.QtWidgets import QComboBox, QMenu

from fluorogui.gui.notices import Notices
from fluorogui.gui.panels.image_items import Tool
from fluorogui.io.errors import InputError


class ModelActions(QObject):
    """The active component and the placing of its model in a main window."""

    def __init__(self, controller, panels: list, notices: Notices) -> None:
        super().__init__(notices.parent_widget)
        self.controller = c = controller
        self.panels = panels
        self.notices = notices
        self.place_clicks: dict[int, tuple[float, float]] = {}
        self.last_place_miss: float | None = None
        self.component_actions = QActionGroup(self)
        self.component_menu = QMenu("Active &component", notices.parent_widget)
        self.component_combo = QComboBox()
        self.component_combo.setToolTip("The component whose outline and pose you edit")
        self.component_combo.currentTextChanged.connect(lambda t: t and c.set_component(t))
        for panel in panels:
            panel.point_clicked.connect(self.place_click)
        c.project_replaced.connect(self._project_replaced)
        c.component_changed.connect(self._component_changed)

    # -- the active component -----------------------------------------------------------------
    def _project_replaced(self) -> None:
        c = self.controller
        self.place_clicks.clear()
        names = c.session.components()
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
            action = QAction(name, self.notices.parent_widget, checkable=True)
            action.setChecked(name == c.component)
            action.triggered.connect(lambda _=False, n=name: c.set_component(n))
            self.component_actions.addAction(action)
            self.component_menu.addAction(action)

    def _component_changed(self, name: str) -> None:
        self.component_combo.blockSignals(True)
        self.component_combo.setCurrentText(name)
        self.component_combo.blockSignals(False)
        for action in self.component_actions.actions():
            action.setChecked(action.text() == name)

    # -- placing the model ----------------------------------------------------------------------
    def tool_changed(self, tool: Tool) -> None:
        """The Place tool starts a new pair of clicks."""
        if tool == Tool.PLACE:
            self.place_clicks.clear()
            self.notices.status(f"Click the {self.controller.component} component in view 1, then in view 2", 10000)

    def place_click(self, view: int, u: float, v: float) -> None:
        c = self.controller
        self.place_clicks[view] = (u, v)
        if len(self.place_clicks) < 2:
            other = 2 if view == 0 else 1
            self.notices.status(f"Now click the {c.component} component in view {other}", 10000)
            return
        pixels = [self.place_clicks[0], self.place_clicks[1]]
        self.place_clicks.clear()
        for panel in self.panels:
            panel.clear_place_marker()
        try:
            miss = c.session.place_at(c.component, c.frame, pixels)
        except (InputError, KeyError, ValueError) as exc:
            self.notices.warn("Cannot place the model", str(exc))
            return
        quality = "good" if miss < 5 else "check that you clicked the same part in both views"
        self.notices.status(f"Placed the {c.component} model: the rays miss by {miss:.1f} mm ({quality})", 10000)
        self.last_place_miss = miss

    def orient(self, angles) -> None:
        c = self.controller
        try:
            c.session.orient(c.component, c.frame, angles)
        except (InputError, KeyError) as exc:
            self.notices.warn("Cannot orient the model", str(exc))
