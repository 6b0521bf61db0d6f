"""The matcher panel: method and densities, Match / Track (active component or both), Find
implants, Cancel, a live objective plot, the pose status of the frame on screen, progress
and the summary of the last task.

The panel only collects settings and shows what it is told; the main window runs the
work. ``describe_pose`` puts a pose record's status and reason in plain words; a long
reason is shown as one line per component (its first problem and how many more, cut to
the panel's width: ``one_line``), with the whole text on demand (*Details*).
"""
from __future__ import annotations

import dataclasses
import html
import math

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QFont, QFontMetrics, QPainter, QPainterPath, QPen
from PySide6.QtWidgets import (
    QComboBox,
    QFormLayout,
    QFrame,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QSizePolicy,
    QSpinBox,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from fluorogui.core.matching.problem import MatchSettings
from fluorogui.core.records import PoseRecord
from fluorogui.core.status import Status

DENSITIES = ((3500, "3 500 points (quick look)"), (15000, "15 000 points (paper)"), (25000, "25 000 points (fine)"))
LEVEL_COLOURS = {"ok": "#3cb45a", "bad": "#e12d2d", "warn": "#e6aa28", "": None}


def describe_pose(component: str, record: PoseRecord | None) -> tuple[str, str]:
    """One line on a component's pose in a frame, and its level: "ok" (matched or
    accepted), "bad" (needs review or failed: never shown as matched) or ""."""
    if record is None:
        return f"{component}: not placed or matched in this frame", ""
    numbers = ""
    if record.match is not None:
        m = record.match
        numbers = f", {m.objective_mm:.3f} mm ({m.calls} calls, {m.seconds:.1f} s)"
    if record.reviewed:
        flagged = f"; it had been flagged: {record.reason}" if record.status != Status.MATCHED and record.reason else ""
        return f"{component}: accepted{numbers}{flagged}", "ok"
    if record.status == Status.MATCHED:
        return f"{component}: matched{numbers}", "ok"
    if record.status == Status.NEEDS_REVIEW:
        why = record.reason or "a quality check failed"
        return f"{component}: needs review — {why}{numbers}", "bad"
    if record.status == Status.FAILED:
        why = record.reason or "no pose could be found"
        return f"{component}: failed — {why}", "bad"
    return f"{component}: placed, not matched yet (F5 matches it)", ""


def one_line(text: str, metrics: QFontMetrics, width: int) -> str:
    """``text`` in one line of ``width`` px: its first problem (a reason's problems are
    joined by "; ", ``core.matching.quality.judge``), cut with "…" where it is too long,
    and how many more problems there are."""
    parts = text.split("; ")
    more = f" (+{len(parts) - 1} more)" if len(parts) > 1 else ""
    room = max(20, width - metrics.horizontalAdvance(more))
    return metrics.elidedText(parts[0], Qt.TextElideMode.ElideRight, room) + more


class ObjectivePlot(QWidget):
    """Objective (mm, log scale) against objective call, drawn with QPainter (cheap to update)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.values: list[float] = []
        self.setMinimumHeight(64)
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
    run_both_requested = Signal()
    cancel_requested = Signal()
    track_requested = Signal()
    track_both_requested = Signal()
    accept_requested = Signal()
    unaccept_requested = Signal()
    place_requested = Signal()
    settings_edited = Signal()  # the user changed method, density or outline points

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
        self.density.setEnabled(False)  # the fast method matches the mesh itself
        self.outline_points = QSpinBox()
        self.outline_points.setRange(0, 1000)
        self.outline_points.setSpecialValueText("auto")
        self.outline_points.setValue(0)
        self.outline_points.setToolTip(
            "Outline points per view (auto: model one per px, image one per 2 px; paper: 60)")
        self.method.currentIndexChanged.connect(lambda _i: self.settings_edited.emit())
        self.method.currentIndexChanged.connect(lambda _i: self._show_density())
        self.density.currentIndexChanged.connect(lambda _i: self.settings_edited.emit())
        self.outline_points.valueChanged.connect(lambda _v: self.settings_edited.emit())
        form = QFormLayout()
        form.addRow("Method", self.method)
        sizes = QHBoxLayout()
        sizes.addWidget(self.density, 3)
        sizes.addWidget(QLabel("outline"))
        sizes.addWidget(self.outline_points, 1)
        form.addRow("Model points", sizes)

        self.place_button = QPushButton("Find implants")
        self.place_button.setToolTip("Locate every component in both images automatically (Ctrl+F)")
        self.run_button = QPushButton("Match")
        self.run_button.setObjectName("matchButton")
        self.run_button.setToolTip("Match the active component in this frame (F5)")
        self.run_both_button = QPushButton("Match both")
        self.run_both_button.setToolTip("Match every component in this frame, each masked where the other "
                                        "overlaps it (Ctrl+F5)")
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setToolTip("Stop the running task; the poses stay as they were (Esc)")
        self.cancel_button.setEnabled(False)
        self.track_button = QPushButton("Track")
        self.track_button.setToolTip("Track the active component through the frames after this one (Shift+F5)")
        self.track_both_button = QPushButton("Track both")
        self.track_both_button.setToolTip("Track every component through the frames after this one "
                                          "(Ctrl+Shift+F5)")
        self.accept_button = QPushButton("Accept")
        self._accepted: bool | None = None  # None: nothing to accept yet
        self._focus_back: QWidget | None = None  # the control that had the focus when a task started
        for button, signal in ((self.place_button, self.place_requested), (self.run_button, self.run_requested),
                               (self.run_both_button, self.run_both_requested),
                               (self.cancel_button, self.cancel_requested), (self.track_button, self.track_requested),
                               (self.track_both_button, self.track_both_requested)):
            button.clicked.connect(signal)
        self.accept_button.clicked.connect(
            lambda: (self.unaccept_requested if self._accepted else self.accept_requested).emit())
        self.set_accepted(None)
        buttons = QGridLayout()
        buttons.addWidget(self.run_button, 0, 0)
        buttons.addWidget(self.run_both_button, 0, 1)
        buttons.addWidget(self.place_button, 0, 2)
        buttons.addWidget(self.track_button, 1, 0)
        buttons.addWidget(self.track_both_button, 1, 1)
        buttons.addWidget(self.accept_button, 1, 2)

        self.plot = ObjectivePlot()
        self.status = QLabel("Ready")
        self.status.setObjectName("matchStatus")
        self.status.setWordWrap(True)
        self.status.setTextFormat(Qt.TextFormat.RichText)
        self.status.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.pose_lines: list = []  # (text, level, active) of the frame on screen
        self.pose_summary = QLabel("")  # one line per component when a reason is long
        self.pose_summary.setObjectName("poseSummary")
        self.pose_summary.setTextFormat(Qt.TextFormat.RichText)
        self.pose_summary.setVisible(False)
        self.details_button = QToolButton()
        self.details_button.setObjectName("poseDetails")
        self.details_button.setCheckable(True)
        self.details_button.setAutoRaise(True)
        self.details_button.setVisible(False)
        self.details_button.toggled.connect(lambda _on: self._show_details())
        self.summary = QLabel("")
        self.summary.setObjectName("taskSummary")
        self.summary.setWordWrap(True)
        self.summary.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.summary.setVisible(False)
        texts = QWidget()
        column = QVBoxLayout(texts)
        column.setContentsMargins(0, 0, 4, 0)
        column.addWidget(self.pose_summary)
        column.addWidget(self.status)
        column.addWidget(self.details_button, 0, Qt.AlignmentFlag.AlignLeft)
        column.addWidget(self.summary)
        column.addStretch(1)
        self.texts = QScrollArea()  # long reasons scroll instead of growing the window
        self.texts.setWidget(texts)
        self.texts.setWidgetResizable(True)
        self.texts.setFrameShape(QFrame.Shape.NoFrame)
        self.texts.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.texts.setMinimumHeight(64)  # two summary lines and Details…, on a laptop too
        self.progress = QProgressBar()
        self.progress.setVisible(False)
        self.progress.setTextVisible(True)
        running = QHBoxLayout()
        running.addWidget(self.progress, 1)
        running.addStretch(0)
        running.addWidget(self.cancel_button)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addLayout(buttons)
        layout.addLayout(running)
        layout.addWidget(self.plot, 2)
        layout.addWidget(self.texts, 3)

    # -- settings ------------------------------------------------------------------------------
    def settings(self, base: MatchSettings | None = None) -> MatchSettings:
        """``base`` (default: the defaults) with the panel's method, density and outline points."""
        n = self.outline_points.value()
        method = self.method.currentData()
        if method == "paper" and n == 0:
            n = 60
        return dataclasses.replace(base or MatchSettings(), method=method, model_points=int(self.density.currentData()),
                                   outline_points=n or None)

    def set_settings(self, settings: MatchSettings) -> None:
        """Show a session's match settings (no ``settings_edited``)."""
        widgets = (self.method, self.density, self.outline_points)
        for w in widgets:
            w.blockSignals(True)
        try:
            i = self.method.findData(settings.method)
            self.method.setCurrentIndex(max(i, 0))
            i = self.density.findData(int(settings.model_points))
            if i < 0:
                self.density.addItem(f"{int(settings.model_points):,} points".replace(",", " "),
                                     int(settings.model_points))
                i = self.density.count() - 1
            self.density.setCurrentIndex(i)
            n = settings.outline_points or 0
            self.outline_points.setValue(0 if settings.method == "paper" and n == 60 else int(n))
        finally:
            for w in widgets:
                w.blockSignals(False)
        self._show_density()

    def _show_density(self) -> None:
        """The point-cloud density only means something to the paper method: greyed out for the fast one."""
        self.density.setEnabled(self.method.currentData() == "paper" and self.run_button.isEnabled())

    def set_accepted(self, accepted: bool | None) -> None:
        """The acceptance of the active pose: False shows *Accept*, True *Un-accept*
        (labelled, never a silent toggle), None (nothing matched yet) a disabled *Accept*."""
        self._accepted = accepted
        if accepted:
            self.accept_button.setText("Un-accept")
            self.accept_button.setToolTip("This pose is accepted; click to take the acceptance back "
                                          "(Ctrl+Shift+Return)")
        else:
            self.accept_button.setText("Accept")
            self.accept_button.setToolTip("Accept the active component's pose in this frame (even a flagged "
                                          "one: you have checked it) (Ctrl+Return)")
        self.accept_button.setEnabled(accepted is not None and self.run_button.isEnabled())

    # -- running ---------------------------------------------------------------------------------
    def set_running(self, running: bool) -> None:
        """Controls off and Cancel on while a task runs, and back. The focus goes to Cancel
        and back itself: a disabled control hands it to the next in the tab chain, and the
        dock's scroll area scrolls to show that one, moving every button."""
        controls = (self.run_button, self.run_both_button, self.track_button, self.track_both_button,
                    self.place_button, self.method, self.outline_points)
        focus = self.window().focusWidget()
        if running:
            self.cancel_button.setEnabled(True)
            if focus in (*controls, self.density, self.accept_button):
                self._focus_back = focus
                self.cancel_button.setFocus(Qt.FocusReason.OtherFocusReason)
        for w in controls:
            w.setEnabled(not running)
        self._show_density()
        self.accept_button.setEnabled(not running and self._accepted is not None)
        if not running:
            back, self._focus_back = self._focus_back, None
            if focus is self.cancel_button:
                (back if back is not None and back.isEnabled() else self.run_button).setFocus(
                    Qt.FocusReason.OtherFocusReason)
        self.cancel_button.setEnabled(running)
        if running:
            self.plot.clear()
        else:
            self.progress.setVisible(False)

    def show_live(self, calls: int, objective_mm: float, history) -> None:
        self.plot.set_values(history)
        self.show_message(f"Matching… call {calls}, objective {objective_mm:.4f} mm")

    def show_message(self, text: str) -> None:
        self.pose_lines = []
        self.status.setText(html.escape(text))
        self._show_details()

    def show_poses(self, lines) -> None:
        """The pose status of the frame on screen: (text, level, active) per component; a
        long one in one line, the whole on demand."""
        self.pose_lines = list(lines)
        self.status.setText("<br>".join(_pose_row(text, level, active) for text, level, active in self.pose_lines)
                            or "No components")
        self._show_details()

    def _summary_rows(self) -> tuple[list[str], bool]:
        """Each pose line cut to one line of the panel's width; whether any was cut."""
        width = max(80, self.texts.viewport().width() - 28)  # less the bullet and margins
        rows, cut = [], False
        for text, level, active in self.pose_lines:
            font = QFont(self.pose_summary.font())
            font.setBold(active)
            short = one_line(text, QFontMetrics(font), width)
            cut = cut or short != text
            rows.append(_pose_row(short, level, active))
        return rows, cut

    def _show_details(self) -> None:
        """The whole pose text, or one line per component with *Details* when it is long."""
        rows, cut = self._summary_rows() if self.pose_lines else ([], False)
        details = self.details_button.isChecked()
        self.details_button.setVisible(cut)
        self.details_button.setText("Hide details" if details else "Details…")
        self.details_button.setToolTip("" if details else "Show every check that failed, in full")
        self.pose_summary.setText("<br>".join(rows))
        self.pose_summary.setToolTip("\n".join(text for text, _, _ in self.pose_lines) if cut else "")
        self.pose_summary.setVisible(cut and not details)
        self.status.setVisible(not cut or details)

    def resizeEvent(self, event) -> None:  # noqa: N802 (Qt override)
        super().resizeEvent(event)
        if self.pose_lines:
            self._show_details()  # cut the lines to the new width

    def show_result(self, record, history=None, label: str = "") -> None:
        """Summarise a MatchRecord (or say there is none)."""
        if history is not None:
            self.plot.set_values(history)
        if record is None:
            self.show_message(label or "Not matched in this frame")
            return
        views = ", ".join(f"{v:.3f}" for v in record.per_view_mean_mm)
        state = "converged" if record.converged else "did not converge"
        self.show_message(f"{label}{record.method}: objective {record.objective_mm:.4f} mm (views {views}), "
                          f"{record.calls} calls, {record.seconds:.2f} s, {state}")

    def show_summary(self, text: str) -> None:
        """What the last task did (kept until the next task ends)."""
        self.summary.setText(text)
        self.summary.setVisible(bool(text))

    def show_progress(self, fraction: float, text: str) -> None:
        """A task's progress as a fraction (0..1) with a few words."""
        self.progress.setVisible(True)
        self.progress.setRange(0, 1000)
        self.progress.setValue(int(round(1000 * min(max(fraction, 0.0), 1.0))))
        self.progress.setFormat(f"{text} (%p %)" if text else "%p %")

    def show_batch(self, done: int, total: int, seconds: float, left_s: float | None = None) -> None:
        """Frames done of ``total`` and the time left: ``left_s`` (a moving average of the
        recent frames, ``fluorogui.gui.eta``) or else the average time per frame so far."""
        self.progress.setVisible(True)
        self.progress.setRange(0, max(total, 1))
        self.progress.setValue(done)
        if done:
            eta = seconds / done * (total - done) if left_s is None else left_s
            left = f"about {eta:.0f} s left" if eta >= 1 or done == total else "under a second left"
            self.progress.setFormat(f"%v / %m frames, {left}")
        else:
            self.progress.setFormat("%v / %m frames")


def _pose_row(text: str, level: str, active: bool) -> str:
    """One component's line as rich text: a coloured bullet for its level, bold when active."""
    row = html.escape(text)
    colour = LEVEL_COLOURS.get(level)
    if colour:
        row = f'<span style="color:{colour}">&#9679;</span> ' + row
    return f"<b>{row}</b>" if active else row
