"""The Kinematics panel: the current frame's six knee values, the side, and the curves
across frames (matplotlib, embedded) where a click goes to that frame; or, chosen beside
them, the contact plot (each condyle's lowest point on the tray against flexion, lift-off
marked: ``workflow.contact_plot``).

It draws what it is given (``set_rows``: ``fluorogui.workflow.session.knee.KneeRow``s;
``set_contact``: ``fluorogui.workflow.contact.ContactRow``s); the presenter computes them
from the session (the anatomical frames are edited in ``dialogs.anatomical_frame``). The
curves keep a readable size (``PLOT_MIN_SIZE``) and scroll when the dock is smaller (a
laptop screen), instead of being squeezed into strips; *Curves in a window* shows them in
a window of their own, sized to the screen (``CurvesWindow``). A long review reason is one
line, the whole on demand (*Details*).
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
from fluorogui.workflow.contact_plot import draw_contact
from fluorogui.workflow.knee_plot import UNITS, draw_kinematics

#: the smallest size (px) the seven plots are drawn at: below it the plot area scrolls
PLOT_MIN_SIZE = (380, 640)
#: the curves window's size where the screen has room for it
CURVES_WINDOW_SIZE = (1000, 820)
SIDE_CHOICES = (("Not set (right assumed)", None), ("Right knee", "right"), ("Left knee", "left"))
PLOT_CHOICES = (("Kinematics", "kinematics"), ("Contact", "contact"))


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
    plot_changed = Signal(str)  # "kinematics" or "contact"

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.rows: list = []
        self.current_frame: int | None = None
        self.contact_rows: list = []
        self.contact_pivot = None
        self.contact_note = "Contact not computed yet."  # why there is no plot, or ""
        self.plot = QComboBox()
        self.plot.setObjectName("kneePlot")
        self.plot.setToolTip("The figure: the knee's six curves, or the condyles' contact on the tray "
                             "(lowest points against flexion, lift-off marked)")
        for text, value in PLOT_CHOICES:
            self.plot.addItem(text, value)
        self.plot.currentIndexChanged.connect(self._plot_changed)
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
        top.addWidget(self.plot, 0, 1)
        top.addWidget(self.against, 0, 2)
        top.addWidget(frames, 1, 0)
        top.addWidget(export, 1, 1)
        top.addWidget(self.window_button, 1, 2)
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

    def shows_contact(self) -> bool:
        return self.plot.currentData() == "contact"

    def set_contact(self, rows: list, pivot=None, note: str = "") -> None:
        """The contact of every frame and its pivot, or ``note`` saying why there is none
        (or that it is being computed); redrawn now when shown."""
        self.contact_rows, self.contact_pivot, self.contact_note = rows, pivot, note
        if self.shows_contact():
            self.redraw()

    def set_current(self, frame: int | None) -> None:
        if frame != self.current_frame and self.shows_contact():
            self._redraw_timer.start()  # the current frame's ring
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
        if self.shows_contact():
            self._redraw_timer.start()  # stacked or side by side, as the dock's shape asks

    def show_curves_window(self) -> None:
        """Open (or raise) the curves in their own window, sized to the screen."""
        if self.curves_window is None:
            self.curves_window = CurvesWindow(self)
            self.curves_window.fit_to_screen()
        self.curves_window.show()
        self.curves_window.raise_()
        self.redraw()

    def _plot_changed(self, _index: int) -> None:
        self.against.setEnabled(not self.shows_contact())  # the contact plot is against flexion
        self.redraw()
        self.plot_changed.emit(self.plot.currentData())

    def _draw(self, figure: Figure, stacked: bool) -> list:
        side = self.side.currentData() or "right"
        palette = self.palette()  # the theme's colours (light or dark)
        colours = tuple(palette.color(role).name() for role in (
            QPalette.ColorRole.Window, QPalette.ColorRole.Base, QPalette.ColorRole.Text))
        if not self.shows_contact():
            return draw_kinematics(figure, self.rows, side=side, against=self.against.currentData(),
                                   current_frame=self.current_frame, colours=colours)
        if self.contact_note:
            figure.clear()
            figure.set_facecolor(colours[0])
            figure.text(0.5, 0.5, self.contact_note, ha="center", va="center", wrap=True, color=colours[2])
            return []
        return draw_contact(figure, self.contact_rows, side=side, pivot=self.contact_pivot, stacked=stacked,
                            current_frame=self.current_frame, colours=colours)

    def redraw(self) -> None:
        self.axes = self._draw(self.figure, stacked=self.canvas.height() > 0.8 * self.canvas.width())
        self.canvas.draw_idle()
        window = self.curves_window
        if window is not None and window.isVisible():
            window.axes = self._draw(window.figure, stacked=False)
            window.canvas.draw_idle()

    # -- what the user does ------------------------------------------------------------------------
    def _side_activated(self, _index: int) -> None:
        value = self.side.currentData()
        if value:
            self.side_chosen.emit(value)

    def frame_near(self, x: float, y: float | None, axes_gid: str | None) -> int | None:
        """The frame of the point nearest a click at data (x, y) in the axes ``axes_gid``."""
        if axes_gid == "contact_tray":
            return self._contact_frame_near(x, y)
        if not self.rows:
            return None
        frames = np.array([r.frame for r in self.rows], dtype=float)
        if axes_gid != "contact_ap" and (self.against.currentData() == "frame" or axes_gid == "residual_mm"):
            return int(frames[np.argmin(np.abs(frames - x))])
        flexion = np.array([r.values.flexion_deg for r in self.rows])
        ok = np.isfinite(flexion)
        if not ok.any():
            return None
        return int(frames[ok][np.argmin(np.abs(flexion[ok] - x))])

    def _contact_frame_near(self, x: float, y: float | None) -> int | None:
        """The frame whose medial or lateral point on the tray is nearest (x, y)."""
        if y is None or not self.contact_rows:
            return None
        points = np.array([[getattr(r.contact, n).lowest[:2] for n in ("medial", "lateral")]
                           for r in self.contact_rows], dtype=float)
        distance = np.nanmin(np.hypot(points[..., 0] - x, points[..., 1] - y), axis=1, initial=np.inf)
        return None if not np.isfinite(distance).any() else int(self.contact_rows[int(np.argmin(distance))].frame)

    def _clicked(self, event) -> None:
        if event.inaxes is None or event.xdata is None:
            return
        frame = self.frame_near(event.xdata, event.ydata, event.inaxes.get_gid())
        if frame is not None:
            self.frame_selected.emit(frame)
