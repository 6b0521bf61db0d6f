"""The Kinematics panel: the current frame's six knee values, the side, and the curves
across frames (matplotlib, embedded) where a click goes to that frame.

It draws what it is given (``set_rows``: ``fluorogui.workflow.session.knee.KneeRow``s); the main
window computes them from the session (the anatomical frames are edited in
``dialogs.anatomical_frame``). The curves keep a readable size (``PLOT_MIN_SIZE``) and
scroll when the dock is smaller (a laptop screen), instead of being squeezed into strips;
*Curves in a window* shows them in a window of their own, sized to the screen
(``CurvesWindow``). A long review reason is one line, the whole on demand (*Details*).
"""
from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QFontMetrics, QGuiApplication, QPalette
from PySide6.QtWidgets import (
    QComboBox,
    QFrame,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from fluorogui.core.knee.kinematics import KINEMATICS_LABELS
from fluorogui.gui.panels.matcher_panel import one_line
from fluorogui.workflow.knee_plot import UNITS, draw_kinematics

#: the smallest size (px) the seven plots are drawn at: below it the plot area scrolls
PLOT_MIN_SIZE = (380, 640)
#: the curves window's size where the screen has room for it
CURVES_WINDOW_SIZE = (1000, 820)
SIDE_CHOICES = (("Not set (right assumed)", None), ("Right knee", "right"), ("Left knee", "left"))


class CurvesWindow(QWidget):
    """The knee curves in a window of their own (a click on a curve goes to that frame)."""

    def __init__(self, panel: "KneePanel") -> None:
        super().__init__(panel, Qt.WindowType.Window)
        self.setObjectName("kneeCurvesWindow")
        self.setWindowTitle("Knee kinematics — fluorogui")
        self.figure = Figure(figsize=(10, 8), dpi=90)
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.mpl_connect("button_press_event", panel._clicked)
        self.axes: list = []
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.canvas)

    def fit_to_screen(self) -> None:
        """``CURVES_WINDOW_SIZE`` or as much of the available screen as there is, centred."""
        screen = self.screen() or QGuiApplication.primaryScreen()
        if screen is None:
            self.resize(*CURVES_WINDOW_SIZE)
            return
        area = screen.availableGeometry()
        width, height = min(CURVES_WINDOW_SIZE[0], area.width() - 16), min(CURVES_WINDOW_SIZE[1], area.height() - 40)
        self.resize(width, height)
        self.move(area.x() + (area.width() - width) // 2, area.y() + max(0, (area.height() - height - 40) // 2))


class KneePanel(QWidget):
    """Six values, the side and the curves of the knee."""

    frame_selected = Signal(int)
    side_chosen = Signal(str)
    export_figure_requested = Signal()
    edit_frames_requested = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.rows: list = []
        self.current_frame: int | None = None
        self.side = QComboBox()
        self.side.setObjectName("kneeSide")
        self.side.setToolTip("Which knee this is: the signs of varus, rotation and medial translation depend on it")
        for text, value in SIDE_CHOICES:
            self.side.addItem(text, value)
        self.side.activated.connect(self._side_activated)
        self.against = QComboBox()
        self.against.addItem("against frame", "frame")
        self.against.addItem("against flexion", "flexion")
        self.against.setToolTip("The curves' horizontal axis")
        self.against.currentIndexChanged.connect(lambda _i: self.redraw())
        export = QPushButton("Save figure…")
        export.setToolTip("Save the figure as PNG, SVG or PDF")
        export.clicked.connect(self.export_figure_requested)
        frames = QPushButton("Anatomical frames…")
        frames.setToolTip("See or edit each component's anatomical frame (x right, y anterior, z proximal)")
        frames.clicked.connect(self.edit_frames_requested)
        self.window_button = QPushButton("Curves in a window")
        self.window_button.setObjectName("kneeCurvesButton")
        self.window_button.setToolTip("Show the curves in a window of their own, as large as the screen allows")
        self.window_button.clicked.connect(self.show_curves_window)
        self.curves_window: CurvesWindow | None = None
        top = QGridLayout()  # rows: a narrow dock keeps every control visible
        top.addWidget(self.side, 0, 0)
        top.addWidget(self.against, 0, 1)
        top.addWidget(self.window_button, 0, 2)
        top.addWidget(frames, 1, 0)
        top.addWidget(export, 1, 1)
        top.setColumnStretch(3, 1)

        self.value_labels: list[QLabel] = []
        values = QGridLayout()
        values.setHorizontalSpacing(14)
        for k, (label, unit) in enumerate(zip(KINEMATICS_LABELS, UNITS)):
            name = QLabel(f"{label} ({unit})")
            value = QLabel("–")
            value.setObjectName(f"knee_value_{k}")
            value.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
            value.setMinimumWidth(60)
            values.addWidget(name, k % 3, 2 * (k // 3))
            values.addWidget(value, k % 3, 2 * (k // 3) + 1)
            self.value_labels.append(value)
        self.status = QLabel("")  # the whole text; hidden behind status_line when long
        self.status.setObjectName("kneeStatus")
        self.status.setWordWrap(True)
        self.status.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.status_line = QLabel("")  # one line, cut to the panel's width
        self.status_line.setObjectName("kneeStatusLine")
        self.status_line.setVisible(False)
        self.details_button = QToolButton()
        self.details_button.setObjectName("kneeDetails")
        self.details_button.setCheckable(True)
        self.details_button.setAutoRaise(True)
        self.details_button.setVisible(False)
        self.details_button.toggled.connect(lambda _on: self._fit_status())
        status_row = QHBoxLayout()
        status_row.setContentsMargins(0, 0, 0, 0)
        status_row.addWidget(self.status_line, 1)
        status_row.addWidget(self.details_button, 0, Qt.AlignmentFlag.AlignTop)

        self.figure = Figure(figsize=(6, 5), dpi=90)
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.setMinimumSize(*PLOT_MIN_SIZE)
        self.canvas.mpl_connect("button_press_event", self._clicked)
        self.plot_area = QScrollArea()
        self.plot_area.setObjectName("kneePlotArea")
        self.plot_area.setWidgetResizable(True)
        self.plot_area.setFrameShape(QFrame.Shape.NoFrame)
        self.plot_area.setWidget(self.canvas)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addLayout(values)
        layout.addLayout(status_row)
        layout.addWidget(self.status)
        layout.addWidget(self.plot_area, 1)
        self.axes: list = []
        self._redraw_timer = QTimer(self)
        self._redraw_timer.setSingleShot(True)
        self._redraw_timer.setInterval(150)  # tracking stores frames in bursts: draw once per burst
        self._redraw_timer.timeout.connect(self.redraw)

    # -- what it shows ---------------------------------------------------------------------------
    def set_side(self, side: str | None) -> None:
        self.side.setCurrentIndex([v for _, v in SIDE_CHOICES].index(side if side in ("right", "left") else None))

    def set_rows(self, rows: list, current_frame: int | None) -> None:
        """The kinematics of every frame (redrawn shortly after) and the current frame."""
        self.rows = rows
        self.set_current(current_frame)
        self._redraw_timer.start()

    def set_current(self, frame: int | None) -> None:
        self.current_frame = frame
        row = next((r for r in self.rows if r.frame == frame), None)
        if row is None:
            for label in self.value_labels:
                label.setText("–")
            self._set_status("No frame")
            return
        for label, value in zip(self.value_labels, row.values.values()):
            label.setText("–" if not np.isfinite(value) else f"{value:.2f}")
        words = {"matched": "Both components matched.", "needs_review": f"Needs review: {row.reason}.",
                 "missing": f"No kinematics: {row.reason}."}
        self._set_status(f"Frame {frame}: {words.get(row.status, row.status)}")
        self.status.setProperty("flagged", row.status != "matched")

    def _set_status(self, text: str) -> None:
        self.status.setText(text)
        self._fit_status()

    def _fit_status(self) -> None:
        """The status in one line when it is longer, with *Details* for the whole."""
        text = self.status.text()
        width = max(60, self.width() - self.details_button.sizeHint().width() - 24)
        line = one_line(text, QFontMetrics(self.status_line.font()), width)
        long = line != text
        details = self.details_button.isChecked()
        self.status_line.setText(line)
        self.status_line.setToolTip(text if long else "")
        self.status_line.setVisible(long and not details)
        self.details_button.setVisible(long)
        self.details_button.setText("Hide details" if details else "Details…")
        self.status.setVisible(not long or details)

    def resizeEvent(self, event) -> None:  # noqa: N802 (Qt override)
        super().resizeEvent(event)
        self._fit_status()

    def show_curves_window(self) -> None:
        """Open (or raise) the curves in their own window, sized to the screen."""
        if self.curves_window is None:
            self.curves_window = CurvesWindow(self)
            self.curves_window.fit_to_screen()
        self.curves_window.show()
        self.curves_window.raise_()
        self.redraw()

    def redraw(self) -> None:
        side = self.side.currentData() or "right"
        palette = self.palette()  # the theme's colours (light or dark)
        colours = tuple(palette.color(role).name() for role in (
            QPalette.ColorRole.Window, QPalette.ColorRole.Base, QPalette.ColorRole.Text))
        self.axes = draw_kinematics(self.figure, self.rows, side=side, against=self.against.currentData(),
                                    current_frame=self.current_frame, colours=colours)
        self.canvas.draw_idle()
        window = self.curves_window
        if window is not None and window.isVisible():
            window.axes = draw_kinematics(window.figure, self.rows, side=side, against=self.against.currentData(),
                                          current_frame=self.current_frame, colours=colours)
            window.canvas.draw_idle()

    # -- what the user does ------------------------------------------------------------------------
    def _side_activated(self, _index: int) -> None:
        value = self.side.currentData()
        if value:
            self.side_chosen.emit(value)

    def frame_near(self, x: float, y: float | None, axes_gid: str | None) -> int | None:
        """The frame of the point nearest a click at data (x, y) in the axes ``axes_gid``."""
        if not self.rows:
            return None
        frames = np.array([r.frame for r in self.rows], dtype=float)
        if self.against.currentData() == "frame" or axes_gid == "residual_mm":
            return int(frames[np.argmin(np.abs(frames - x))])
        flexion = np.array([r.values.flexion_deg for r in self.rows])
        ok = np.isfinite(flexion)
        if not ok.any():
            return None
        return int(frames[ok][np.argmin(np.abs(flexion[ok] - x))])

    def _clicked(self, event) -> None:
        if event.inaxes is None or event.xdata is None:
            return
        frame = self.frame_near(event.xdata, event.ydata, event.inaxes.get_gid())
        if frame is not None:
            self.frame_selected.emit(frame)
