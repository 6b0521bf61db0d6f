"""The matcher panel: method and densities, Run / Cancel / Track, a live objective plot, results.

The panel only collects settings and shows progress; the main window runs the work.
"""
from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QPainter, QPainterPath, QPen
from PySide6.QtWidgets import (
    QComboBox,
    QFormLayout,
    QGridLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QSizePolicy,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from fluorogui.core.matching import MatchSettings

DENSITIES = ((3500, "3 500 points (quick look)"), (15000, "15 000 points (paper)"), (25000, "25 000 points (fine)"))


class ObjectivePlot(QWidget):
    """Objective (mm, log scale) against objective call, drawn with QPainter (cheap to update)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.values: list[float] = []
        self.setMinimumHeight(110)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setToolTip("Objective (sum of the views' mean outline distances, mm) per call")

    def set_values(self, values) -> None:
        self.values = [float(v) for v in values if np.isfinite(v) and v > 0]
        self.update()

    def clear(self) -> None:
        self.set_values([])

    def paintEvent(self, _event) -> None:  # noqa: N802 (Qt override)
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        pal = self.palette()
        p.fillRect(self.rect(), pal.base())
        text = pal.text().color()
        margin_l, margin_b, margin_t, margin_r = 44, 18, 8, 8
        area = QRectF(margin_l, margin_t, max(1, self.width() - margin_l - margin_r),
                      max(1, self.height() - margin_t - margin_b))
        grid = QColor(text)
        grid.setAlpha(50)
        p.setPen(QPen(grid, 1))
        p.drawRect(area)
        p.setPen(text)
        font = p.font()
        font.setPointSizeF(max(6.5, font.pointSizeF() * 0.8))
        p.setFont(font)
        if not self.values:
            p.drawText(area, Qt.AlignmentFlag.AlignCenter, "objective (mm) vs call")
            p.end()
            return
        lo = math.floor(math.log10(min(self.values)))
        hi = math.ceil(math.log10(max(self.values)))
        hi = max(hi, lo + 1)
        n = max(len(self.values) - 1, 1)

        def point(i, v):
            x = area.left() + area.width() * i / n
            y = area.bottom() - area.height() * (math.log10(v) - lo) / (hi - lo)
            return QPointF(x, y)

        for e in range(lo, hi + 1):
            y = area.bottom() - area.height() * (e - lo) / (hi - lo)
            p.setPen(QPen(grid, 1))
            p.drawLine(QPointF(area.left(), y), QPointF(area.right(), y))
            p.setPen(text)
            p.drawText(QRectF(0, y - 8, margin_l - 4, 16), Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter,
                       f"{10.0 ** e:g}")
        p.drawText(QRectF(area.left(), area.bottom() + 2, area.width(), margin_b - 2),
                   Qt.AlignmentFlag.AlignRight, f"{len(self.values)} steps")
        path = QPainterPath(point(0, self.values[0]))
        for i, v in enumerate(self.values[1:], start=1):
            path.lineTo(point(i, v))
        p.setPen(QPen(pal.highlight().color(), 1.6))
        p.drawPath(path)
        p.end()


class MatcherPanel(QWidget):
    """Settings and controls of the matcher, with live feedback."""

    run_requested = Signal()
    cancel_requested = Signal()
    track_requested = Signal()
    accept_requested = Signal()
    place_requested = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.method = QComboBox()
        self.method.addItem("Fast (exact silhouette, analytic LM)", "fast")
        self.method.addItem("Paper (point cloud, finite-difference BFGS)", "paper")
        self.method.setToolTip("'Fast' is the shipped matcher; 'Paper' reproduces the published method")
        self.density = QComboBox()
        for n, label in DENSITIES:
            self.density.addItem(label, n)
        self.density.setCurrentIndex(1)
        self.density.setToolTip("Surface points of the model (used by the paper method)")
        self.outline_points = QSpinBox()
        self.outline_points.setRange(0, 1000)
        self.outline_points.setSpecialValueText("auto")
        self.outline_points.setValue(0)
        self.outline_points.setToolTip("Model outline points per view (auto: one every 2 px; paper: 60)")
        form = QFormLayout()
        form.addRow("Method", self.method)
        form.addRow("Model density", self.density)
        form.addRow("Outline points", self.outline_points)

        self.place_button = QPushButton("Find implants")
        self.place_button.setToolTip("Locate every component in both images automatically")
        self.run_button = QPushButton("Match")
        self.run_button.setObjectName("matchButton")
        self.run_button.setToolTip("Match the active component in this frame (F5)")
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setToolTip("Stop the running match and keep the previous pose (Esc)")
        self.cancel_button.setEnabled(False)
        self.track_button = QPushButton("Track following frames")
        self.track_button.setToolTip("Match the active component in this and every later frame")
        self.accept_button = QPushButton("Accept pose")
        self.accept_button.setToolTip("Mark the active component's pose in this frame as reviewed (Ctrl+Return)")
        for button, signal in ((self.place_button, self.place_requested), (self.run_button, self.run_requested),
                               (self.cancel_button, self.cancel_requested), (self.track_button, self.track_requested),
                               (self.accept_button, self.accept_requested)):
            button.clicked.connect(signal)
        buttons = QGridLayout()
        buttons.addWidget(self.run_button, 0, 0)
        buttons.addWidget(self.cancel_button, 0, 1)
        buttons.addWidget(self.place_button, 1, 0)
        buttons.addWidget(self.accept_button, 1, 1)
        buttons.addWidget(self.track_button, 2, 0, 1, 2)

        self.plot = ObjectivePlot()
        self.status = QLabel("Ready")
        self.status.setObjectName("matchStatus")
        self.status.setWordWrap(True)
        self.status.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.progress = QProgressBar()
        self.progress.setVisible(False)
        self.progress.setTextVisible(True)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addLayout(buttons)
        layout.addWidget(self.plot, 1)
        layout.addWidget(self.progress)
        layout.addWidget(self.status)

    def settings(self) -> MatchSettings:
        n = self.outline_points.value()
        method = self.method.currentData()
        if method == "paper" and n == 0:
            n = 60
        return MatchSettings(method=method, model_points=int(self.density.currentData()),
                             outline_points=n or None)

    def set_running(self, running: bool) -> None:
        for w in (self.run_button, self.track_button, self.place_button, self.accept_button, self.method,
                  self.density, self.outline_points):
            w.setEnabled(not running)
        self.cancel_button.setEnabled(running)
        if running:
            self.plot.clear()
        else:
            self.progress.setVisible(False)

    def show_live(self, calls: int, objective_mm: float, history) -> None:
        self.plot.set_values(history)
        self.status.setText(f"Matching… call {calls}, objective {objective_mm:.4f} mm")

    def show_result(self, record, history=None, label: str = "") -> None:
        """Summarise a MatchRecord (or say there is none)."""
        if history is not None:
            self.plot.set_values(history)
        if record is None:
            self.status.setText(label or "Not matched in this frame")
            return
        views = ", ".join(f"{v:.3f}" for v in record.per_view_mean_mm)
        state = "converged" if record.converged else "NOT converged"
        self.status.setText(
            f"{label}{record.method}: objective {record.objective_mm:.4f} mm (views {views}), "
            f"{record.calls} calls, {record.seconds:.2f} s, {state}")

    def show_batch(self, done: int, total: int, seconds: float) -> None:
        self.progress.setVisible(True)
        self.progress.setRange(0, total)
        self.progress.setValue(done)
        eta = seconds / done * (total - done) if done else float("nan")
        self.progress.setFormat(f"%v / %m frames, about {eta:.0f} s left" if done else "%v / %m frames")
