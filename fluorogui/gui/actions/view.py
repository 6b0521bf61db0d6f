"""The View menu of the main window: fit the images, show the edges with their two Canny
thresholds (toolbar sliders, remembered in the settings) and the theme. The actions are
declared in ``gui.layout.actions``; ``ViewActions`` is given the checkable ones it keeps
in step and makes the sliders the toolbar shows."""
from __future__ import annotations

from PySide6.QtCore import QObject, QSettings, Qt
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QApplication, QSlider

from fluorogui.gui import theme

CANNY_SLIDERS = (  # settings key, default (%), tooltip
    ("low", 10, "Canny low threshold (% of the strong-edge gradient)"),
    ("high", 30, "Canny high threshold (% of the strong-edge gradient)"),
)


class ViewActions(QObject):
    """How a main window's images look: fit, edges and their thresholds, the theme."""

    def __init__(self, settings: QSettings, panels: list, *, edges_action: QAction,
                 theme_actions: dict[str, QAction]) -> None:
        """``edges_action``: *Show edges* (checkable); ``theme_actions``: one per theme name."""
        super().__init__(edges_action)
        self.settings = settings
        self.panels = panels
        self.edges_action = edges_action
        sliders = []
        for key, value, tip in CANNY_SLIDERS:
            slider = QSlider(Qt.Orientation.Horizontal)
            slider.setRange(1, 100)
            slider.setValue(int(self.settings.value(f"canny/{key}", value)))
            slider.setFixedWidth(80)
            slider.setToolTip(tip)
            slider.valueChanged.connect(self._thresholds_changed)
            sliders.append(slider)
        self.low_slider, self.high_slider = sliders
        for name, action in theme_actions.items():
            if name == self.settings.value("theme", "system"):
                action.setChecked(True)

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

    def save_settings(self) -> None:
        self.settings.setValue("canny/low", self.low_slider.value())
        self.settings.setValue("canny/high", self.high_slider.value())

    def set_theme(self, name: str) -> None:
        self.settings.setValue("theme", name)
        app = QApplication.instance()
        if app is not None:
            theme.apply_theme(app, name)
