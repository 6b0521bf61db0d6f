"""Look and feel: the Fusion style with a light or dark palette (following the system by
default), a small style sheet, and icons from ``fluorogui/resources/icons`` (package data)."""
from __future__ import annotations

from PySide6.QtCore import QRectF, Qt
from PySide6.QtGui import QColor, QGuiApplication, QIcon, QPainter, QPalette, QPen
from PySide6.QtWidgets import QApplication, QFocusFrame, QProxyStyle, QStyle, QWidget

from fluorogui.resources import ICON_DIR

THEMES = ("system", "light", "dark")

STYLE = """
QLabel#hint { color: palette(mid); font-size: 8.5pt; }
QLabel#poseTitle { padding: 2px 0 4px 0; }
QPushButton#matchButton { font-weight: bold; }
QDockWidget::title { padding: 4px 6px; font-weight: bold; }
QToolBar { spacing: 2px; }
"""


def icon(name: str) -> QIcon:
    """A toolbar icon by name (an empty icon if the file is missing)."""
    path = ICON_DIR / f"{name}.svg"
    return QIcon(str(path)) if path.exists() else QIcon()


def system_prefers_dark() -> bool:
    hints = QGuiApplication.styleHints()
    scheme = getattr(hints, "colorScheme", None)
    return bool(scheme and scheme() == Qt.ColorScheme.Dark)


def dark_palette() -> QPalette:
    p = QPalette()
    window, base, text = QColor(37, 40, 46), QColor(27, 29, 34), QColor(222, 226, 232)
    roles = {
        QPalette.ColorRole.Window: window,
        QPalette.ColorRole.WindowText: text,
        QPalette.ColorRole.Base: base,
        QPalette.ColorRole.AlternateBase: QColor(44, 48, 55),
        QPalette.ColorRole.ToolTipBase: QColor(55, 60, 68),
        QPalette.ColorRole.ToolTipText: text,
        QPalette.ColorRole.Text: text,
        QPalette.ColorRole.Button: QColor(50, 54, 62),
        QPalette.ColorRole.ButtonText: text,
        QPalette.ColorRole.BrightText: QColor(255, 90, 90),
        QPalette.ColorRole.Highlight: QColor(70, 130, 210),
        QPalette.ColorRole.HighlightedText: QColor(255, 255, 255),
        QPalette.ColorRole.Link: QColor(110, 160, 230),
        QPalette.ColorRole.Mid: QColor(120, 126, 136),
        QPalette.ColorRole.PlaceholderText: QColor(130, 136, 146),
    }
    for role, colour in roles.items():
        p.setColor(role, colour)
    for role in (QPalette.ColorRole.Text, QPalette.ColorRole.ButtonText, QPalette.ColorRole.WindowText):
        p.setColor(QPalette.ColorGroup.Disabled, role, QColor(110, 114, 122))
    return p


def light_palette() -> QPalette:
    p = QApplication.style().standardPalette()
    p.setColor(QPalette.ColorRole.Highlight, QColor(45, 110, 200))
    p.setColor(QPalette.ColorRole.Mid, QColor(130, 134, 140))
    return p


class FocusStyle(QProxyStyle):
    """Fusion, with a focus frame that can be seen: a 2 px ring in the highlight colour
    around the widget with keyboard focus (Fusion's own is a faint tint)."""

    def drawControl(self, element, option, painter, widget=None):  # noqa: N802 (Qt override)
        if element == QStyle.ControlElement.CE_FocusFrame:
            painter.save()
            painter.setRenderHint(QPainter.RenderHint.Antialiasing)
            painter.setPen(QPen(option.palette.color(QPalette.ColorRole.Highlight), 2.0))
            painter.setBrush(Qt.BrushStyle.NoBrush)
            painter.drawRoundedRect(QRectF(option.rect).adjusted(1, 1, -1, -1), 3, 3)
            painter.restore()
            return
        super().drawControl(element, option, painter, widget)

    def pixelMetric(self, metric, option=None, widget=None):  # noqa: N802 (Qt override)
        if metric in (QStyle.PixelMetric.PM_FocusFrameHMargin, QStyle.PixelMetric.PM_FocusFrameVMargin):
            return 2
        return super().pixelMetric(metric, option, widget)


def install_focus_frame(window: QWidget) -> QFocusFrame:
    """A focus ring that follows keyboard focus inside ``window`` (drawn by FocusStyle)."""
    frame = QFocusFrame(window)
    frame.setObjectName("focusFrame")
    frame.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)

    def follow(_old, new) -> None:
        try:
            inside = new is not None and new.window() is window and new.isVisible()
            frame.setWidget(new if inside else None)
        except RuntimeError:  # the window or the widget is being deleted
            _disconnect(QApplication.instance(), follow)

    app = QApplication.instance()
    if app is not None:
        app.focusChanged.connect(follow)
        window.destroyed.connect(lambda *_: _disconnect(app, follow))
    return frame


def _disconnect(app, slot) -> None:
    try:
        app.focusChanged.disconnect(slot)
    except (RuntimeError, TypeError):
        pass


def apply_theme(app: QApplication, theme: str = "system") -> str:
    """Apply a theme ("system", "light" or "dark"); returns the one in effect."""
    if not isinstance(app.style(), FocusStyle):
        app.setStyle(FocusStyle("Fusion"))
    dark = system_prefers_dark() if theme == "system" else theme == "dark"
    app.setPalette(dark_palette() if dark else light_palette())
    app.setStyleSheet(STYLE)
    return "dark" if dark else "light"
