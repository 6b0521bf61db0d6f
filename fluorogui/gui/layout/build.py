"""Making the main window's Qt objects from its specs: the docks of ``PanelSpec``s, the
actions of ``ActionSpec``s (bound to the presenters by key, enabled by the ``Context``),
and the menus and toolbar where the specs place them. Nothing here knows a particular
panel or action."""
from __future__ import annotations

from collections.abc import Iterable
from types import SimpleNamespace

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction, QActionGroup, QKeySequence
from PySide6.QtWidgets import QDockWidget, QFrame, QMainWindow, QMenu, QScrollArea, QToolBar

from fluorogui.gui import theme
from fluorogui.gui.layout.specs import (
    MENUBAR,
    TOOLBAR,
    ActionSpec,
    Context,
    MenuSpec,
    PanelSpec,
    Parts,
    Place,
    WidgetSpec,
)


# -- docks -------------------------------------------------------------------------------------------
def _dock(window: QMainWindow, spec: PanelSpec, content) -> QDockWidget:
    """A dock; with ``scroll`` its content scrolls when the window is too small for it
    (a laptop screen) instead of squeezing or overlapping."""
    dock = QDockWidget(spec.title, window)
    dock.setObjectName(spec.name)
    if spec.scroll:
        area = QScrollArea()
        area.setObjectName(f"{spec.name}Scroll")
        area.setWidgetResizable(True)
        area.setFrameShape(QFrame.Shape.NoFrame)
        area.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAsNeeded)
        area.setWidget(content)
        area.setMinimumSize(160, 90)
        content = area
    dock.setWidget(content)
    window.addDockWidget(spec.area, dock)
    if spec.features is not None:
        dock.setFeatures(spec.features)
    return dock


def build_docks(window: QMainWindow, panels: Iterable[PanelSpec], parts: Parts) -> dict[str, QDockWidget]:
    """Make each panel's widget (``parts.widgets.<key>``) and dock it, in the order
    declared; a panel that joins another's tabs is tabified with it, and the group's
    ``raised`` tab is brought back on top. Returns the docks by panel key."""
    docks: dict[str, QDockWidget] = {}
    raised: list[QDockWidget] = []
    for spec in panels:
        content = spec.widget(parts)
        if content is None:
            continue
        setattr(parts.widgets, spec.key, content)
        dock = docks[spec.key] = _dock(window, spec, content)
        if spec.raised:
            raised.append(dock)
        if spec.tab_with is not None and spec.tab_with in docks:
            window.tabifyDockWidget(docks[spec.tab_with], dock)
            for top in raised:
                top.raise_()
    return docks


def menu_order(panels: Iterable[PanelSpec], docks: dict[str, QDockWidget]) -> list[str]:
    """The keys of the panels as the View menu lists them: in the order declared, except
    that the raised tab of a tab group comes after the group's other tabs (as the window
    has always listed them)."""
    specs = [spec for spec in panels if spec.key in docks]
    group: dict[str, str] = {}
    for spec in specs:
        group[spec.key] = group[spec.tab_with] if spec.tab_with in group else spec.key
    order = [spec.key for spec in specs]
    for spec in specs:
        if spec.raised:
            order.remove(spec.key)
            others = [i for i, key in enumerate(order) if group[key] == group[spec.key]]
            order.insert(others[-1] + 1 if others else [s.key for s in specs].index(spec.key), spec.key)
    return order


# -- actions -----------------------------------------------------------------------------------------
def key_sequences(shortcut) -> list[QKeySequence]:
    """The key sequences of a spec's ``shortcut``: one, or every one of a tuple (a
    standard key with all the platform's bindings of it), each once, in order."""
    if shortcut is None:
        return []
    if not isinstance(shortcut, tuple):
        return [QKeySequence(shortcut)]
    keys: list[QKeySequence] = []
    for key in shortcut:
        standard = isinstance(key, QKeySequence.StandardKey)
        keys += list(QKeySequence.keyBindings(key)) if standard else [QKeySequence(key)]
    unique = dict.fromkeys(k.toString(QKeySequence.SequenceFormat.PortableText) for k in keys if not k.isEmpty())
    return [QKeySequence(k) for k in unique]


def build_actions(window: QMainWindow, specs: Iterable[ActionSpec], presenters: SimpleNamespace,
                  context: Context) -> dict[str, QAction]:
    """An action of the window per spec, in the order declared (its shortcut works
    anywhere in the window, and F1 lists it); triggering it runs the spec's ``run`` with
    the presenters (looked up then, so the actions can be made before them). Actions
    with ``enabled_when`` follow the context. Returns the actions by id."""
    actions: dict[str, QAction] = {}
    groups: dict[str, QActionGroup] = {}
    ruled: list[tuple[ActionSpec, QAction]] = []
    for spec in specs:
        if spec.id in actions:
            raise ValueError(f"two actions have the id {spec.id!r}")
        action = QAction(spec.title, window)
        keys = key_sequences(spec.shortcut)
        if len(keys) == 1 and not isinstance(spec.shortcut, tuple):
            action.setShortcut(keys[0])
        elif keys:
            action.setShortcuts(keys)
        if spec.icon:
            action.setIcon(theme.icon(spec.icon))
        if spec.tip:
            action.setToolTip(spec.tip)
            action.setStatusTip(spec.tip)
        if spec.checkable:
            action.setCheckable(True)
            action.setChecked(spec.checked)
        if spec.exclusive:
            groups.setdefault(spec.exclusive, QActionGroup(window)).addAction(action)
        if spec.run is not None:
            action.triggered.connect(lambda _checked=False, run=spec.run: run(presenters))
        if spec.enabled_when:
            ruled.append((spec, action))
            action.setEnabled(context.holds(spec.enabled_when))
        window.addAction(action)
        actions[spec.id] = action

    def follow(changed: set[str]) -> None:
        for spec, action in ruled:
            if any(key.lstrip("!") in changed for key in spec.enabled_when):
                action.setEnabled(context.holds(spec.enabled_when))

    context.listeners.append(follow)
    return actions


# -- menus and the toolbar ---------------------------------------------------------------------------
class _Items:
    """What each container (menu id, MENUBAR, TOOLBAR) holds, in the order it is shown."""

    def __init__(self) -> None:
        self._items: dict[str, list] = {}

    def add(self, place: Place, kind: str, payload) -> None:
        items = self._items.setdefault(place.menu, [])
        items.append((place.group, place.order, len(items), kind, payload))

    def of(self, menu: str) -> list[tuple[str, str, object]]:
        """(group, kind, payload) of a container's items, sorted."""
        return [(group, kind, payload) for group, _order, _n, kind, payload in sorted(self._items.get(menu, []),
                                                                                     key=lambda i: i[:3])]

    def grouped(self, menu: str):
        """(whether a separator comes first, kind, payload) of a container's items: one
        between two groups."""
        last = None
        for group, kind, payload in self.of(menu):
            yield last is not None and group != last, kind, payload
            last = group


def build_menus(window: QMainWindow, menus: Iterable[MenuSpec], specs: Iterable[ActionSpec],
                actions: dict[str, QAction], *, presenters: SimpleNamespace, panel_toggles: Place,
                toggles: Iterable[QAction]) -> dict[str, QMenu]:
    """The menu bar's menus and submenus with the actions the specs place in them, a
    separator between two groups; the panels' check boxes (``toggles``) go to
    ``panel_toggles``. Returns the menus by id."""
    items = _Items()
    for menu in menus:
        items.add(menu.place, "menu", menu)
    for spec in specs:
        for place in spec.places:
            if place.menu != TOOLBAR:
                items.add(place, "action", actions[spec.id])
    for toggle in toggles:
        items.add(panel_toggles, "action", toggle)
    built: dict[str, QMenu] = {}

    def fill(menu: QMenu, menu_id: str) -> None:
        for separated, kind, payload in items.grouped(menu_id):
            if separated:
                menu.addSeparator()
            if kind == "action":
                menu.addAction(payload)
            else:
                built[payload.id] = sub = _submenu(menu, payload)
                if payload.provided is None:
                    fill(sub, payload.id)

    def _submenu(menu: QMenu, spec: MenuSpec) -> QMenu:
        if spec.provided is not None:
            provided = spec.provided(presenters)
            menu.addMenu(provided)
            return provided
        return menu.addMenu(spec.title)

    bar = window.menuBar()
    for _group, _kind, spec in items.of(MENUBAR):
        built[spec.id] = menu = bar.addMenu(spec.title)
        fill(menu, spec.id)
    return built


def build_toolbar(window: QMainWindow, title: str, name: str, specs: Iterable[ActionSpec],
                  widgets: Iterable[WidgetSpec], actions: dict[str, QAction], presenters: SimpleNamespace) -> QToolBar:
    """The toolbar (icons only) with the actions and widgets placed on it, a separator
    between two groups."""
    items = _Items()
    for spec in specs:
        for place in spec.places:
            if place.menu == TOOLBAR:
                items.add(place, "action", actions[spec.id])
    for widget in widgets:
        items.add(widget.place, "widget", widget)
    bar = window.addToolBar(title)
    bar.setObjectName(name)
    bar.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonIconOnly)
    for separated, kind, payload in items.grouped(TOOLBAR):
        if separated:
            bar.addSeparator()
        if kind == "action":
            bar.addAction(payload)
        else:
            bar.addWidget(payload.make(presenters))
    return bar
