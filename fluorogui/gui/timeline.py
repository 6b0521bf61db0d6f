"""The frame timeline: one cell per frame coloured by its state, click or arrow keys to move."""
from __future__ import annotations

from PySide6.QtCore import QRectF, Qt, Signal
from PySide6.QtGui import QColor, QPainter, QPen
from PySide6.QtWidgets import QSizePolicy, QToolTip, QWidget

from fluorogui.gui.controller import FrameState

STATE_COLOURS = {
    FrameState.EMPTY: QColor(120, 120, 120),
    FrameState.OUTLINED: QColor(230, 170, 40),
    FrameState.MATCHED: QColor(60, 130, 220),
    FrameState.REVIEWED: QColor(60, 180, 90),
}
STATE_NAMES = {
    FrameState.EMPTY: "no outline",
    FrameState.OUTLINED: "outlined",
    FrameState.MATCHED: "matched",
    FrameState.REVIEWED: "reviewed",
}


class Timeline(QWidget):
    """A strip of frame cells; the current one is framed."""

    frame_selected = Signal(int)  # index

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.frames: list[int] = []
        self.states: list[FrameState] = []
        self.current = 0
        self.setMinimumHeight(34)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setMouseTracking(True)
        self.setAccessibleName("Frame timeline")
        self.setToolTip("Frames: grey no outline, amber outlined, blue matched, green reviewed")

    def set_frames(self, frames, states) -> None:
        self.frames = list(frames)
        self.states = list(states)
        self.current = min(self.current, max(0, len(self.frames) - 1))
        self.update()

    def set_states(self, states) -> None:
        self.states = list(states)
        self.update()

    def set_current(self, index: int) -> None:
        self.current = index
        self.update()

    def _cell(self, i: int) -> QRectF:
        n = max(1, len(self.frames))
        w = (self.width() - 8) / n
        return QRectF(4 + i * w, 6, max(1.0, w - (1 if w > 4 else 0)), self.height() - 12)

    def index_at(self, x: float) -> int:
        n = len(self.frames)
        if not n:
            return -1
        return int(min(n - 1, max(0, (x - 4) / max(1e-9, (self.width() - 8) / n))))

    def paintEvent(self, _event) -> None:  # noqa: N802 (Qt override)
        p = QPainter(self)
        p.fillRect(self.rect(), self.palette().window())
        for i in range(len(self.frames)):
            state = self.states[i] if i < len(self.states) else FrameState.EMPTY
            p.fillRect(self._cell(i), STATE_COLOURS[state])
        if self.frames:
            p.setPen(QPen(self.palette().text().color(), 2))
            p.drawRect(self._cell(self.current).adjusted(-1, -3, 1, 3))
            cell = self._cell(self.current)
            if cell.width() > 22:
                p.setPen(Qt.GlobalColor.white)
                p.drawText(cell, Qt.AlignmentFlag.AlignCenter, str(self.frames[self.current]))
        p.end()

    def mousePressEvent(self, event) -> None:  # noqa: N802 (Qt override)
        i = self.index_at(event.position().x())
        if i >= 0:
            self.frame_selected.emit(i)

    def mouseMoveEvent(self, event) -> None:  # noqa: N802 (Qt override)
        i = self.index_at(event.position().x())
        if i >= 0:
            state = self.states[i] if i < len(self.states) else FrameState.EMPTY
            QToolTip.showText(event.globalPosition().toPoint(), f"Frame {self.frames[i]}: {STATE_NAMES[state]}", self)
        if event.buttons() & Qt.MouseButton.LeftButton and i >= 0 and i != self.current:
            self.frame_selected.emit(i)

    def keyPressEvent(self, event) -> None:  # noqa: N802 (Qt override)
        step = {Qt.Key.Key_Left: -1, Qt.Key.Key_Right: 1}.get(event.key())
        if step and self.frames:
            self.frame_selected.emit(max(0, min(len(self.frames) - 1, self.current + step)))
        elif event.key() == Qt.Key.Key_Home and self.frames:
            self.frame_selected.emit(0)
        elif event.key() == Qt.Key.Key_End and self.frames:
            self.frame_selected.emit(len(self.frames) - 1)
        else:
            super().keyPressEvent(event)
