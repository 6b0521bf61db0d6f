"""The frame timeline: one cell per frame coloured by its state, click or arrow keys to move.

Frames are addressed by their numbers (``frame_selected`` emits one, ``set_current`` and
``set_state`` take one); positions in the strip are internal. A frame that needs review
(a check failed, or no pose could be found) has a colour of its own and is never shown
as matched. ``TimelineLegend`` explains the colours beside the strip; ``FramesBar`` holds
the two side by side (the Frames panel).
"""
from __future__ import annotations

from PySide6.QtCore import QRectF, Qt, Signal
from PySide6.QtGui import QColor, QPainter, QPen
from PySide6.QtWidgets import QHBoxLayout, QLabel, QSizePolicy, QToolTip, QWidget

from fluorogui.workflow.session import FrameState

STATE_COLOURS = {
    FrameState.EMPTY: QColor(120, 120, 120),
    FrameState.OUTLINED: QColor(230, 170, 40),
    FrameState.MATCHED: QColor(60, 130, 220),
    FrameState.REVIEWED: QColor(60, 180, 90),
    FrameState.NEEDS_REVIEW: QColor(225, 45, 45),
}
STATE_NAMES = {
    FrameState.EMPTY: "no outline",
    FrameState.OUTLINED: "outlined or placed",
    FrameState.MATCHED: "matched",
    FrameState.REVIEWED: "accepted",
    FrameState.NEEDS_REVIEW: "needs review",
}
LEGEND_ORDER = (FrameState.EMPTY, FrameState.OUTLINED, FrameState.MATCHED, FrameState.NEEDS_REVIEW,
                FrameState.REVIEWED)
LEGEND_TEXT = ", ".join(f"{STATE_NAMES[s]} ({c})" for s, c in zip(
    LEGEND_ORDER, ("grey", "amber", "blue", "red", "green")))


class TimelineLegend(QWidget):
    """The timeline's colours, one swatch and word each."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(4, 0, 4, 0)
        layout.setSpacing(10)
        for state in LEGEND_ORDER:
            swatch = QLabel()
            swatch.setFixedSize(12, 12)
            swatch.setStyleSheet(f"background: {STATE_COLOURS[state].name()}; border-radius: 2px;")
            layout.addWidget(swatch)
            label = QLabel(STATE_NAMES[state])
            label.setContentsMargins(0, 0, 4, 0)
            layout.addWidget(label)
        self.setToolTip("Frame colours: " + LEGEND_TEXT)


class Timeline(QWidget):
    """A strip of frame cells; the current one is framed."""

    frame_selected = Signal(int)  # frame number

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.frames: list[int] = []
        self.states: list[FrameState] = []
        self._position: dict[int, int] = {}
        self.notes: dict[int, str] = {}  # frame -> why it needs review (in the tooltip)
        self.current = 0  # position of the framed cell
        self.setMinimumHeight(34)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setMouseTracking(True)
        self.setAccessibleName("Frame timeline")
        self.setToolTip("Frames: " + LEGEND_TEXT)

    def set_frames(self, frames, states) -> None:
        self.frames = list(frames)
        self.states = list(states)
        self._position = {f: i for i, f in enumerate(self.frames)}
        self.notes = {}
        self.current = min(self.current, max(0, len(self.frames) - 1))
        self.update()

    def set_states(self, states) -> None:
        self.states = list(states)
        self.update()

    def set_state(self, frame: int, state: FrameState) -> None:
        """The state of one frame (by number)."""
        i = self._position.get(frame)
        if i is not None and i < len(self.states) and self.states[i] != state:
            self.states[i] = state
            self.update()

    def set_note(self, frame: int, text: str) -> None:
        """Why a frame needs review ("" clears it): shown in the frame's tooltip."""
        if text:
            self.notes[frame] = text
        else:
            self.notes.pop(frame, None)

    def state(self, frame: int) -> FrameState:
        i = self._position.get(frame)
        return self.states[i] if i is not None and i < len(self.states) else FrameState.EMPTY

    def set_current(self, frame: int) -> None:
        """Frame the cell of frame number ``frame``."""
        i = self._position.get(frame)
        if i is not None and i != self.current:
            self.current = i
            self.update()

    @property
    def current_frame(self) -> int | None:
        return self.frames[self.current] if self.frames else None

    def cell_rect(self, frame: int) -> QRectF | None:
        """Where a frame's cell is drawn (widget coordinates)."""
        i = self._position.get(frame)
        return None if i is None else self._cell(i)

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
            self.frame_selected.emit(self.frames[i])

    def mouseMoveEvent(self, event) -> None:  # noqa: N802 (Qt override)
        i = self.index_at(event.position().x())
        if i >= 0:
            state = self.states[i] if i < len(self.states) else FrameState.EMPTY
            note = self.notes.get(self.frames[i])
            QToolTip.showText(event.globalPosition().toPoint(),
                              f"Frame {self.frames[i]}: {STATE_NAMES[state]}" + (f"\n{note}" if note else ""), self)
        if event.buttons() & Qt.MouseButton.LeftButton and i >= 0 and i != self.current:
            self.frame_selected.emit(self.frames[i])

    def keyPressEvent(self, event) -> None:  # noqa: N802 (Qt override)
        step = {Qt.Key.Key_Left: -1, Qt.Key.Key_Right: 1}.get(event.key())
        if step and self.frames:
            self.frame_selected.emit(self.frames[max(0, min(len(self.frames) - 1, self.current + step))])
        elif event.key() == Qt.Key.Key_Home and self.frames:
            self.frame_selected.emit(self.frames[0])
        elif event.key() == Qt.Key.Key_End and self.frames:
            self.frame_selected.emit(self.frames[-1])
        else:
            super().keyPressEvent(event)


class FramesBar(QWidget):
    """The Frames panel: the timeline with its legend beside it."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        row = QHBoxLayout(self)
        row.setContentsMargins(0, 0, 0, 0)
        self.timeline = Timeline()
        row.addWidget(self.timeline, 1)
        self.legend = TimelineLegend()
        row.addWidget(self.legend)
