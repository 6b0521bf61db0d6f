"""The Kinematics panel: the current frame's six knee values, the side, and the curves
across frames (matplotlib, embedded) where a click goes to that frame.

It draws what it is given (``set_rows``: ``fluorogui.workflow.knee.KneeRow``s); the main
window computes them from the session (the anatomical frames are edited in
``dialogs.anatomical_frame``).
"""
from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QPalette
from PySide6.QtWidgets import (
    QComboBox,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from fluorogui.core.knee.kinematics import KINEMATICS_LABELS
from fluorogui.workflow.knee_plot import UNITS, draw_kinematics

SIDE_CHOICES = (("Not set (right assumed)", None), ("Right knee", "right"), ("Left knee", "left"))


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
        top = QHBoxLayout()
        for w in (self.side, self.against, frames, export):
            top.addWidget(w)
        top.addStretch(1)

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
        self.status = QLabel("")
        self.status.setObjectName("kneeStatus")
        self.status.setWordWrap(True)

        self.figure = Figure(figsize=(6, 5), dpi=90)
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.setMinimumHeight(220)
        self.canvas.mpl_connect("button_press_event", self._clicked)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addLayout(values)
        layout.addWidget(self.status)
        layout.addWidget(self.canvas, 1)
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
            self.status.setText("No frame")
            return
        for label, value in zip(self.value_labels, row.values.values()):
            label.setText("–" if not np.isfinite(value) else f"{value:.2f}")
        words = {"matched": "Both components matched.", "needs_review": f"Needs review: {row.reason}.",
                 "missing": f"No kinematics: {row.reason}."}
        self.status.setText(f"Frame {frame}: {words.get(row.status, row.status)}")
        self.status.setProperty("flagged", row.status != "matched")

    def redraw(self) -> None:
        side = self.side.currentData() or "right"
        palette = self.palette()  # the theme's colours (light or dark)
        colours = tuple(palette.color(role).name() for role in (
            QPalette.ColorRole.Window, QPalette.ColorRole.Base, QPalette.ColorRole.Text))
        self.axes = draw_kinematics(self.figure, self.rows, side, self.against.currentData(),
                                    current_frame=self.current_frame, colours=colours)
        self.canvas.draw_idle()

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
