"""Pieces of the image panel: the tool enum, colours, the scene items that draw outlines and
markers at a fixed screen size, the undo command of an edit, the image's value table and
the labels drawn over the image."""
from __future__ import annotations

import enum
import functools
import sys
from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import (
    QBrush,
    QColor,
    QFont,
    QFontMetrics,
    QPainter,
    QPainterPath,
    QPen,
    QPolygonF,
    QUndoCommand,
)
from PySide6.QtWidgets import (
    QGraphicsItem,
    QGraphicsPathItem,
    QGraphicsScene,
)

from fluorogui.core.outlines import editing as oe


class Tool(enum.Enum):
    """What a left click / drag does in the image."""

    NAVIGATE = "Navigate"
    PICK_CONTOUR = "Pick contour"
    MOVE = "Move point"
    INSERT = "Insert point"
    DELETE = "Delete point"
    ERASE = "Erase"
    LASSO = "Lasso delete"
    CLOSE_GAP = "Close gap"
    PLACE = "Place"


BACKGROUND = QColor(18, 19, 23)
DEFAULT_COLOURS = {"femoral": QColor(70, 155, 255), "tibial": QColor(70, 215, 115)}
EXTRA_COLOURS = (QColor(255, 160, 60), QColor(200, 120, 255), QColor(60, 210, 220), QColor(240, 90, 120))
EDGE_RGBA = (255, 190, 0, 170)  # Canny edges: amber, semi-transparent
MODEL_COLOUR = QColor(255, 95, 205)  # projected model outline before its component has a colour
HIGHLIGHT = QColor(255, 255, 255)
FLAGGED_COLOUR = QColor(255, 70, 50)  # the model outline of a pose that needs review
PLACE_COLOUR = QColor(255, 235, 60)

#: distance (px) -> colour stops of the projected model outline: green, yellow, red
DISTANCE_STOPS = (1.0, 3.0, 5.0)
STOP_RGB = np.array([[40, 205, 70], [245, 220, 40], [235, 50, 40]], dtype=float)

PICK_TOLERANCE_PX = 10.0  # screen pixels within which a click hits a point or contour
MIN_SCALE, MAX_SCALE = 0.02, 64.0


def distance_colours(distances) -> np.ndarray:
    """RGB (N, 3) uint8 for model outline distances (px): green up to 1 px, yellow at 3 px,
    red from 5 px; distances are quantised to 0.25 px so there are few distinct colours."""
    d = np.round(np.nan_to_num(np.asarray(distances, dtype=float), nan=np.inf, posinf=1e9) * 4.0) / 4.0
    return np.column_stack([np.interp(d, DISTANCE_STOPS, STOP_RGB[:, c]) for c in range(3)]).round().astype(np.uint8)


def guarded(handler):
    """Event handler wrapper (of an object with a ``_drag``): an error abandons the gesture
    and goes to sys.excepthook instead of unwinding through Qt's event dispatch (which is
    not exception-safe). Returns what the handler returns, True (handled) after an error."""

    @functools.wraps(handler)
    def wrapper(self, event):
        try:
            return handler(self, event)
        except Exception:  # noqa: BLE001 (reported, not hidden)
            self._drag = None
            event.accept()
            sys.excepthook(*sys.exc_info())
            return True

    return wrapper


def polygon(points: np.ndarray) -> QPolygonF:
    return QPolygonF([QPointF(u, v) for u, v in np.asarray(points, dtype=float).tolist()])


def add_spline_runs(solid: QPainterPath, gaps: QPainterPath, spline) -> int:
    """Draw a closed outline spline into ``solid``, except across its gaps (erased or
    missing stretches, ``spline.gaps``), which go into ``gaps`` to be drawn dashed: an
    erased stretch shows as a gap, not as a bridged line. Returns the number of gaps."""
    start, end = spline.t_range
    n = int(np.clip(spline.length_px, 64, 8000))
    t = start + (end - start) * np.arange(n + 1) / n
    curve = spline.evaluate(t)
    in_gap = spline.in_gap(t)
    if not in_gap.any():
        solid.addPolygon(polygon(curve[:-1]))
        solid.closeSubpath()
        return 0
    # runs of samples start where in_gap changes; the closing sample equals the first
    change = np.flatnonzero(np.diff(in_gap.astype(np.int8))) + 1
    bounds = np.concatenate([[0], change, [len(t)]])
    for a, b in zip(bounds[:-1], bounds[1:]):
        lo, hi = max(a - 1, 0), min(b + 1, len(t))  # overlap one sample so runs meet
        (gaps if in_gap[a] else solid).addPolygon(polygon(curve[lo:hi]))
    return len(spline.gaps)


def cosmetic_pen(colour: QColor, width: float, style=Qt.PenStyle.SolidLine) -> QPen:
    pen = QPen(colour, width, style, Qt.PenCapStyle.RoundCap, Qt.PenJoinStyle.RoundJoin)
    pen.setCosmetic(True)
    return pen


# -- scene items ------------------------------------------------------------------------------------
class DotsItem(QGraphicsItem):
    """Round markers a fixed number of screen pixels wide at any zoom (cosmetic pens),
    optionally with a dark halo, one colour or one colour per point."""

    def __init__(self, size_px: float, colour: QColor, halo: bool = True, min_gap_px: float = 0.0):
        super().__init__()
        self._size = float(size_px)
        self._min_gap = float(min_gap_px)  # hide the markers when they would be closer than this
        self._spacing = np.inf
        self._colour = QColor(colour)
        self._halo = halo
        self._points = np.zeros((0, 2))
        self._rgb: np.ndarray | None = None
        self._groups: list[tuple[QColor, QPolygonF]] = []
        self._all = QPolygonF()
        self._rect = QRectF()
        self._margin = self._size
        self.setAcceptedMouseButtons(Qt.MouseButton.NoButton)

    def set_points(self, points, rgb: np.ndarray | None = None) -> None:
        self.prepareGeometryChange()
        pts = np.zeros((0, 2)) if points is None else np.asarray(points, dtype=float).reshape(-1, 2)
        self._points = pts
        self._rgb = None if rgb is None else np.asarray(rgb, dtype=np.uint8).reshape(-1, 3)
        if len(pts) == 0:
            self._rect, self._all, self._groups = QRectF(), QPolygonF(), []
        else:
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            self._rect = QRectF(lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1])
            self._all = polygon(pts)
            self._spacing = oe.outline_spacing(pts) if len(pts) > 1 else np.inf
            self._regroup()
        self.update()

    def _regroup(self) -> None:
        if self._rgb is None or len(self._rgb) != len(self._points):
            self._groups = [(self._colour, self._all)]
            return
        colours, inverse = np.unique(self._rgb, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        self._groups = [(QColor(*map(int, c)), polygon(self._points[inverse == g])) for g, c in enumerate(colours)]

    def colours(self) -> list[QColor]:
        """The colour of each point."""
        if self._rgb is None or len(self._rgb) != len(self._points):
            return [QColor(self._colour) for _ in range(len(self._points))]
        return [QColor(*map(int, c)) for c in self._rgb]

    def set_style(self, size_px: float | None = None, colour: QColor | None = None, halo: bool | None = None) -> None:
        if size_px is not None:
            self._size = float(size_px)
        if colour is not None:
            self._colour = QColor(colour)
            if self._rgb is None and len(self._points):
                self._groups = [(self._colour, self._all)]
        if halo is not None:
            self._halo = halo
        self.update()

    def set_pixel_scale(self, scale: float) -> None:
        """Screen pixels per scene pixel: sets the bounding margin that holds a marker."""
        margin = (self._size / 2.0 + 3.0) / max(scale, 1e-6)
        if abs(margin - self._margin) > 1e-9:
            self.prepareGeometryChange()
            self._margin = margin

    def boundingRect(self) -> QRectF:  # noqa: N802 (Qt override)
        if self._rect.isNull() and not len(self._points):
            return QRectF()
        m = self._margin
        return self._rect.adjusted(-m, -m, m, m)

    def markers_shown(self, scale: float) -> bool:
        """Whether the markers are drawn at ``scale`` screen pixels per image pixel (dense
        markers are left out until zoomed in, so the line under them stays readable)."""
        return bool(len(self._points)) and self._spacing * scale >= self._min_gap

    def paint(self, painter: QPainter, option, widget=None) -> None:
        if not self.markers_shown(painter.worldTransform().m11()):
            return
        painter.setRenderHint(QPainter.RenderHint.Antialiasing, True)
        if self._halo:
            painter.setPen(cosmetic_pen(QColor(0, 0, 0, 200), self._size + 2.5))
            painter.drawPoints(self._all)
        for colour, polygon in self._groups:
            painter.setPen(cosmetic_pen(colour, self._size))
            painter.drawPoints(polygon)


class CrossItem(QGraphicsItem):
    """A cross a fixed number of screen pixels big (the placed point)."""

    def __init__(self, size_px: float = 9.0):
        super().__init__()
        self._size = size_px
        self.setFlag(QGraphicsItem.GraphicsItemFlag.ItemIgnoresTransformations, True)
        self.setAcceptedMouseButtons(Qt.MouseButton.NoButton)

    def boundingRect(self) -> QRectF:  # noqa: N802 (Qt override)
        s = self._size + 3
        return QRectF(-s, -s, 2 * s, 2 * s)

    def paint(self, painter: QPainter, option, widget=None) -> None:
        painter.setRenderHint(QPainter.RenderHint.Antialiasing, True)
        s = self._size
        for colour, width in ((QColor(0, 0, 0, 210), 4.0), (PLACE_COLOUR, 2.0)):
            painter.setPen(QPen(colour, width, Qt.PenStyle.SolidLine, Qt.PenCapStyle.RoundCap))
            painter.drawLine(QPointF(-s, 0), QPointF(s, 0))
            painter.drawLine(QPointF(0, -s), QPointF(0, s))
        painter.setPen(QPen(PLACE_COLOUR, 1.5))
        painter.setBrush(Qt.BrushStyle.NoBrush)
        painter.drawEllipse(QPointF(0, 0), s * 0.45, s * 0.45)


class ComponentItems:
    """The items and state of one component's outline and projected model outline."""

    def __init__(self, scene: QGraphicsScene, colour: QColor):
        self.colour = QColor(colour)
        self.key = None
        self.points: np.ndarray | None = None
        self.spline_ok = False
        self.model_points: np.ndarray | None = None
        self.model_distances: np.ndarray | None = None
        self.flagged = False  # the model's pose needs review
        self.spline = QGraphicsPathItem()
        self.spline.setZValue(4)
        self.gap_line = QGraphicsPathItem()  # chords across erased or missing stretches: dashed
        self.gap_line.setZValue(4)
        self.gap_count = 0
        self.dots = DotsItem(5.0, colour, min_gap_px=6.0)
        self.dots.setZValue(5)
        self.model_line = QGraphicsPathItem()
        self.model_line.setZValue(2)
        self.model_dots = DotsItem(3.0, MODEL_COLOUR, halo=False)
        self.model_dots.setZValue(6)
        for item in (self.spline, self.gap_line, self.dots, self.model_line, self.model_dots):
            item.setAcceptedMouseButtons(Qt.MouseButton.NoButton)
            scene.addItem(item)


class EditCommand(QUndoCommand):
    """An undoable edit made of (redo, undo) steps; undo runs them in reverse."""

    def __init__(self, text: str, steps: list[tuple[Callable[[], None], Callable[[], None]]]):
        super().__init__(text)
        self._steps = steps

    def redo(self) -> None:
        for do, _ in self._steps:
            do()

    def undo(self) -> None:
        for _, undo in reversed(self._steps):
            undo()


class AnonymousImage:
    """Key of an image set without a key (its erased-edge mask lives until the next one)."""


def quantise(arr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An image as indices into a table of its values (computed once), so that window /
    level is a lookup table: (index image, value of each index)."""
    if arr.dtype == np.uint8:
        return arr, np.arange(256, dtype=float)
    if arr.dtype.kind in "iu" and arr.dtype.itemsize <= 2:
        lo = int(arr.min())
        return (arr.astype(np.int32) - lo).astype(np.uint16), lo + np.arange(int(arr.max()) - lo + 1, dtype=float)
    data = np.asarray(arr, dtype=np.float64)
    finite = np.isfinite(data)
    lo = float(data[finite].min()) if finite.any() else 0.0
    hi = float(data[finite].max()) if finite.any() else 1.0
    span = hi - lo if hi > lo else 1.0
    scaled = np.where(finite, (data - lo) * (65535.0 / span), 0.0)
    return np.clip(np.rint(scaled), 0, 65535).astype(np.uint16), lo + np.arange(65536, dtype=float) * (span / 65535.0)


def draw_label(painter: QPainter, font: QFont, corner: QPointF, lines) -> None:
    """A rounded, translucent box with lines of text (optionally a colour swatch each)."""
    fm = QFontMetrics(font)
    swatch = any(colour is not None for colour, _ in lines)
    pad, gap = 6, 2
    width = max(fm.horizontalAdvance(text) for _, text in lines) + 2 * pad + (18 if swatch else 0)
    height = len(lines) * fm.height() + (len(lines) - 1) * gap + 2 * pad
    box = QRectF(corner.x(), corner.y(), width, height)
    painter.setPen(Qt.PenStyle.NoPen)
    painter.setBrush(QColor(0, 0, 0, 150))
    painter.drawRoundedRect(box, 5, 5)
    painter.setFont(font)
    y = box.top() + pad
    for colour, text in lines:
        x = box.left() + pad
        if colour is not None:
            painter.setPen(Qt.PenStyle.NoPen)
            painter.setBrush(QBrush(colour))
            painter.drawRoundedRect(QRectF(x, y + fm.height() / 2 - 5, 12, 10), 2, 2)
            x += 18
        painter.setPen(QColor(235, 235, 235))
        painter.drawText(QPointF(x, y + fm.ascent()), text)
        y += fm.height() + gap
