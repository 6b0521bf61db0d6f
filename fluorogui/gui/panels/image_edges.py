"""The image panel's edge layer: the Canny edges of the shown image at the panel's
thresholds, the pixels erased from them per image, the overlay item that shows them and
the sub-pixel contours the contour picker chooses from.

``EdgeLayer`` is a plain object the panel owns. It keeps its own state (the image it
was shown, its key, the thresholds, the caches and the erased masks) and depends only on
the graphics scene it draws into and a callable that repaints the view."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import QGraphicsItem, QGraphicsPixmapItem, QGraphicsScene

from fluorogui.core.outlines import editing as oe
from fluorogui.core.outlines.edges import DEFAULT_HIGH, DEFAULT_LOW, canny_edges
from fluorogui.core.outlines.edges import edge_contours as find_edge_contours
from fluorogui.gui.panels.image_items import EDGE_RGBA


class EdgeLayer:
    """Canny edges, erased pixels and edge contours of the image a panel shows."""

    def __init__(self, scene: QGraphicsScene, repaint: Callable[[], None]) -> None:
        self._repaint = repaint
        self.image: np.ndarray | None = None
        self.image_key = None
        self._visible = False
        self._thresholds = (DEFAULT_LOW, DEFAULT_HIGH)
        self._canny: np.ndarray | None = None
        self._contours: list[np.ndarray] | None = None
        self._erased: dict[object, np.ndarray] = {}
        self.item = QGraphicsPixmapItem()
        self.item.setOffset(-0.5, -0.5)
        self.item.setZValue(1)
        self.item.setVisible(False)
        self.item.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        scene.addItem(self.item)

    # -- the image ---------------------------------------------------------------------------------
    def show_image(self, image: np.ndarray | None, key=None) -> None:
        """The edges of another image (None: none); ``key`` names its erased mask."""
        self.image, self.image_key = image, (None if image is None else key)
        self._canny = None
        self._contours = None
        if image is None:
            self.item.setPixmap(QPixmap())
            return
        self.refresh()

    def forget(self, keys=None) -> None:
        """Drop the erased masks of ``keys`` (default: of every image)."""
        for key in list(self._erased) if keys is None else keys:
            self._erased.pop(key, None)

    def erased_keys(self) -> list:
        return list(self._erased)

    def set_transformation_mode(self, mode: Qt.TransformationMode) -> None:
        self.item.setTransformationMode(mode)

    # -- visibility and thresholds -----------------------------------------------------------------
    def set_visible(self, visible: bool) -> None:
        self._visible = bool(visible)
        self.refresh()

    def visible(self) -> bool:
        return self._visible

    def set_thresholds(self, low: float, high: float) -> None:
        """Canny thresholds as fractions of the reference gradient (see core.outlines.edges)."""
        if not 0 < low <= high:
            raise ValueError("Canny thresholds must satisfy 0 < low <= high")
        if (float(low), float(high)) == self._thresholds:
            return
        self._thresholds = (float(low), float(high))
        self._canny = None
        self._contours = None
        self.refresh()

    def thresholds(self) -> tuple[float, float]:
        return self._thresholds

    # -- masks -------------------------------------------------------------------------------------
    def canny_mask(self) -> np.ndarray | None:
        """The Canny edges of the image (the cached array), None without an image."""
        if self.image is None:
            return None
        if self._canny is None:
            self._canny = canny_edges(np.asarray(self.image, dtype=np.float32), *self._thresholds)
        return self._canny

    def erased_mask(self, key=None) -> np.ndarray | None:
        """The erased-edge mask (True where edges were erased) of the image ``key`` (default:
        the current one); a copy, None when nothing was erased there."""
        key = self.image_key if key is None else key
        mask = self._erased.get(key)
        return None if mask is None else mask.copy()

    def erased_for(self, key, shape) -> np.ndarray:
        """The erased mask of image ``key`` itself (made empty when missing or of another shape)."""
        mask = self._erased.get(key)
        if mask is None or mask.shape != tuple(shape):
            mask = self._erased[key] = np.zeros(shape, dtype=bool)
        return mask

    def set_erased(self, key, shape, flat: np.ndarray, value: bool) -> None:
        """Mark pixels (flat indices) of image ``key`` erased or not (an edit, its undo)."""
        mask = self.erased_for(key, shape)
        mask.flat[flat] = value
        if key == self.image_key:
            self.refresh()

    def mask(self) -> np.ndarray | None:
        """The edges as shown: Canny edges minus erased pixels (None without an image)."""
        canny = self.canny_mask()
        if canny is None:
            return None
        erased = self._erased.get(self.image_key)
        return canny & ~erased if erased is not None and erased.shape == canny.shape else canny.copy()

    def refresh(self, erased_override: np.ndarray | None = None) -> None:
        """Redraw the overlay (with ``erased_override`` as the erased pixels: a stroke in progress)."""
        if not self._visible or self.image is None:
            self.item.setVisible(False)
            self._repaint()
            return
        edges = self.canny_mask()
        if erased_override is not None:
            edges = edges & ~erased_override
        else:
            edges = self.mask()
        h, w = edges.shape
        rgba = np.zeros((h, w, 4), dtype=np.uint8)
        rgba[edges] = EDGE_RGBA
        qimage = QImage(rgba.data, w, h, 4 * w, QImage.Format.Format_RGBA8888)
        self.item.setPixmap(QPixmap.fromImage(qimage))
        self.item.setVisible(True)
        self._repaint()

    def contours(self) -> list[np.ndarray]:
        """Sub-pixel edge contours of the image at the current thresholds, cut where edges
        were erased (what PICK_CONTOUR chooses from)."""
        if self.image is None:
            return []
        if self._contours is None:
            self._contours = find_edge_contours(np.asarray(self.image, dtype=np.float32), *self._thresholds)
        erased = self._erased.get(self.image_key)
        if erased is None or not erased.any():
            return [c for c in self._contours if len(c) >= 3]
        pieces = []
        for contour in self._contours:
            pieces.extend(p for p in oe.split_at_mask(contour, erased) if len(p) >= 3)
        return pieces
