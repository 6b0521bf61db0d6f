"""What can be declared of the main window, as plain frozen records.

* ``ActionSpec``: one action (id, title, what it runs, where it is shown, its shortcut,
  icon, tooltip, whether it is checkable, and the state it is enabled in);
* ``MenuSpec``: a menu of the menu bar or a submenu, possibly one a presenter fills
  (*Open recent*, *Active component*);
* ``WidgetSpec``: a widget on the toolbar (the component list, the Canny sliders);
* ``PanelSpec``: a dock (title, object name, area, its widget and its presenter);
* ``PresenterSpec``: a presenter that belongs to no single panel (the File menu's ...);
* ``WindowLayout``: all of them, what a ``MainWindow`` is built from.

Besides: the ``Context`` whose keys decide which actions are enabled, and the ``Parts``
(the window's controller, runner, settings, ``Notices`` ..., its widgets and presenters
by key) that factories are given.

Where a thing is shown is a ``Place``: the id of a container (a menu's id, ``MENUBAR``
or ``TOOLBAR``), a group and an order. Groups are sorted by name, with a separator
between two groups; in a group, items follow their order, then the order they are
declared in (as napari's app-model does). ``enabled_when`` names keys of the window's
``Context`` ("running"; "!running": not running): the action is enabled when all hold.

Handlers get what they need by name: an action's ``run`` is called with the window's
presenters (``run=lambda p: p.files.save()``; Qt's ``checked`` argument is not passed
on), a presenter's or a panel's factory with the window's ``Parts``.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import KW_ONLY, dataclass, field, replace
from types import SimpleNamespace
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import QDockWidget

MENUBAR = "menubar"
TOOLBAR = "toolbar"

#: a key sequence: portable text ("Ctrl+E") or one of the platform's standard keys
Key = str | QKeySequence.StandardKey


@dataclass(frozen=True)
class Place:
    """Where an item is shown: in container ``menu`` (a menu id, MENUBAR or TOOLBAR),
    in ``group`` (groups sorted by name, separated), at ``order`` in its group."""

    menu: str
    group: str = ""
    order: float = 0


@dataclass(frozen=True)
class ActionSpec:
    """One action of the main window.

    ``shortcut``: one key sequence, or a tuple of them (all bound, each once; a standard
    key in a tuple brings every binding the platform gives it). An action with a shortcut
    works anywhere in the window and is listed by *Help → Keyboard shortcuts* (in the
    order the actions are declared). ``exclusive``: actions naming the same group are
    checked one at a time. ``enabled_when``: context keys that must all hold (``"!key"``:
    must not); without it a presenter may set the enabled state itself. ``run`` None: the
    action is given to a presenter that connects it itself (Undo and Redo, which follow
    the session's history)."""

    id: str
    title: str
    run: Callable[[Any], object] | None
    places: tuple[Place, ...] = ()
    _: KW_ONLY
    shortcut: Key | tuple[Key, ...] | None = None
    icon: str | None = None
    tip: str = ""
    checkable: bool = False
    checked: bool = False
    exclusive: str | None = None
    enabled_when: tuple[str, ...] = ()


@dataclass(frozen=True)
class MenuSpec:
    """A menu placed in the menu bar (``Place(MENUBAR, order=…)``) or in another menu.
    ``provided``: the menu is a presenter's own, filled as the session changes (called
    with the presenters; ``title`` is then the presenter's)."""

    id: str
    title: str
    place: Place
    provided: Callable[[Any], Any] | None = None


@dataclass(frozen=True)
class WidgetSpec:
    """A widget placed on the toolbar; ``make`` is called with the presenters."""

    id: str
    make: Callable[[Any], Any]
    place: Place


@dataclass(frozen=True)
class PanelSpec:
    """A dock of the main window.

    ``key``: its name among the window's widgets and presenters (``window.widgets.<key>``,
    ``window.docks[key]``); ``name``: the dock's object name, by which a saved window
    layout restores it (never change it); ``widget(parts)`` makes its content (None: the
    panel is left out of this window, e.g. the 3D scene without OpenGL);
    ``presenter(parts, widget)`` makes what keeps it in step with the session and turns
    its signals into session calls (None: other presenters draw it). ``tab_with``: the key
    of the panel whose tabs it joins; ``raised``: the tab shown on top of its group;
    ``scroll``: its content scrolls instead of squeezing on a small screen; ``features``:
    the dock's Qt features (default: movable, floatable, closable); ``actions``: the
    panel's own actions (built after the window's, run like them with the presenters).
    The View menu has a check box per panel."""

    key: str
    title: str
    name: str
    area: Qt.DockWidgetArea
    widget: Callable[[Parts], Any]
    presenter: Callable[[Parts, Any], object] | None = None
    tab_with: str | None = None
    raised: bool = False
    scroll: bool = False
    features: QDockWidget.DockWidgetFeature | None = None
    actions: tuple[ActionSpec, ...] = ()


@dataclass(frozen=True)
class PresenterSpec:
    """A presenter of the main window that is not one panel's; ``make(parts)`` builds it
    with what it needs. Presenters are built in the order declared, before the panels'."""

    key: str
    make: Callable[[Parts], object]


class Context:
    """Named yes / no facts about the window ("running", "pose_accepted" ...) that decide
    which actions are enabled; ``set`` tells the listeners which keys changed. A key
    never set is false."""

    def __init__(self) -> None:
        self._keys: dict[str, bool] = {}
        self.listeners: list[Callable[[set[str]], None]] = []

    def __getitem__(self, key: str) -> bool:
        return self._keys.get(key, False)

    def set(self, **keys: bool) -> None:
        changed = {k for k, v in keys.items() if self[k] != bool(v)}
        self._keys.update({k: bool(v) for k, v in keys.items()})
        if changed:
            for listener in list(self.listeners):
                listener(changed)

    def holds(self, condition: tuple[str, ...]) -> bool:
        """Whether every key of ``condition`` holds (``"!key"``: does not)."""
        return all(not self[k[1:]] if k.startswith("!") else self[k] for k in condition)


@dataclass
class Parts:
    """What the main window is made of, as its factories see it: the window's own parts,
    the widgets of its panels and its presenters (each a namespace filled by key as they
    are built) and its actions by id."""

    window: Any
    controller: Any
    runner: Any
    settings: Any
    notices: Any
    context: Context
    panels: list
    with_3d: bool
    status_labels: SimpleNamespace
    widgets: SimpleNamespace = field(default_factory=SimpleNamespace)
    presenters: SimpleNamespace = field(default_factory=SimpleNamespace)
    actions: dict = field(default_factory=dict)


@dataclass(frozen=True)
class WindowLayout:
    """Everything the main window is built from. ``panel_toggles``: where the View menu
    lists the panels; ``toolbar``: the toolbar's title and object name."""

    menus: tuple[MenuSpec, ...]
    actions: tuple[ActionSpec, ...]
    toolbar_widgets: tuple[WidgetSpec, ...]
    panels: tuple[PanelSpec, ...]
    presenters: tuple[PresenterSpec, ...]
    panel_toggles: Place
    toolbar: tuple[str, str]

    def adding(self, **more: Iterable) -> WindowLayout:
        """This layout with more specs after its own, e.g. ``adding(panels=[toy], actions=[count])``."""
        return replace(self, **{name: getattr(self, name) + tuple(specs) for name, specs in more.items()})

    def all_actions(self) -> tuple[ActionSpec, ...]:
        """The window's actions, then the panels' own, in the order declared."""
        return self.actions + tuple(action for panel in self.panels for action in panel.actions)
