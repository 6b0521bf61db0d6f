"""The main window's whole declaration: its menus, actions and toolbar (``actions``) and its
panels and presenters (``panels``), as one ``WindowLayout`` that ``MainWindow`` builds.
A variant adds specs: ``WINDOW.adding(panels=[...], actions=[...])``."""
from __future__ import annotations

from fluorogui.gui.layout.actions import (
    ACTIONS,
    MENUS,
    PANEL_TOGGLES,
    TOOLBAR_NAME,
    TOOLBAR_TITLE,
    TOOLBAR_WIDGETS,
)
from fluorogui.gui.layout.panels import PANELS, PRESENTERS
from fluorogui.gui.layout.specs import WindowLayout

WINDOW = WindowLayout(menus=MENUS, actions=ACTIONS, toolbar_widgets=TOOLBAR_WIDGETS, panels=PANELS,
                      presenters=PRESENTERS, panel_toggles=PANEL_TOGGLES, toolbar=(TOOLBAR_TITLE, TOOLBAR_NAME))
