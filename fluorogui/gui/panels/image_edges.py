"""The image panel's edge layer: the Canny edges of the shown image at the panel's
thresholds, the pixels erased from them per image, the overlay that shows them and the
sub-pixel contours the contour picker chooses from. A mixin of ``ImagePanel``, which owns
the state it reads (``_image``, ``_image_key``, ``_thresholds``, ``_canny``,
``_contours``, ``_erased``, ``_edges_visible``, ``_edge_item``)."""
from __future__ import annotations

import numpy as np
from PySide6.QtGui import QImage, QPixmap

from fluorogui.core.outlines import editing as oe
from fluorogui.core.outlines.edges import canny_edges
from fluorogui.core.outlines.edges import edge_contours as find_edge_contours
from fluorogui.gui.panels.image_items import EDGE_RGBA


class EdgeLayer:
    """Canny edges, erased pixels and edge contours of an ``ImagePanel``'s image."""

    def set_edges_visible(self, visible: bool) -> None:
        self._edges_visible = bool(visible)
        self._refresh_edges()

    def edges_visible(self) -> bool:
        return self._edges_visible

    def set_canny_thresholds(self, low: float, high: float) -> None:
        """Canny thresholds as fractions of the reference gradient (see core.edges)."""
        if not 0 < low <= high:
            raise ValueError("Canny thresholds must satisfy 0 < low <= high")
        if (float(low), float(high)) == self._thresholds:
            return
        self._thresholds = (float(low), float(high))
        self._canny = None
        self._contours = None
        self._refresh_edges()

    def canny_thresholds(self) -> tuple[float, float]:
        return self._thresholds

    def _canny_mask(self) -> np.ndarray | None:
        if self._image is None:
            return None
        if self._canny is None:
            self._canny = canny_edges(np.asarray(self._image, dtype=np.float32), *self._thresholds)
        return self._canny

    def erased_mask(self, key=None) -> np.ndarray | None:
        """The erased-edge mask (True where edges were erased) of the image ``key`` (default:
        the current one); a copy, None when nothing was erased there."""
        key = self._image_key if key is None else key
        mask = self._erased.get(key)
        return None if mask is None else mask.copy()

    def _erased_for(self, key, shape) -> np.ndarray:
        mask = self._erased.get(key)
        if mask is None or mask.shape != tuple(shape):
            mask = self._erased[key] = np.zeros(shape, dtype=bool)
        return mask

    def edge_mask(self) -> np.ndarray | None:
        """The edges as shown: Canny edges minus erased pixels (None without an image)."""
        canny = self._canny_mask()
        if canny is None:
            return None
        erased = self._erased.get(self._image_key)
        return canny & ~erased if erased is not None and erased.shape == canny.shape else canny.copy()

    def _refresh_edges(self, erased_override: np.ndarray | None = None) -> None:
        if not self._edges_visible or self._image is None:
            self._edge_item.setVisible(False)
            self.viewport().update()
            return
        edges = self._canny_mask()
        if erased_override is not None:
            edges = edges & ~erased_override
        else:
            edges = self.edge_mask()
        h, w = edges.shape
        rgba = np.zeros((h, w, 4), dtype=np.uint8)
        rgba[edges] = EDGE_RGBA
        qimage = QImage(rgba.data, w, h, 4 * w, QImage.Format.Format_RGBA8888)
        self._edge_item.setPixmap(QPixmap.fromImage(qimage))
        self._edge_item.setVisible(True)
        self.viewport().update()

    def edge_contours(self) -> list[np.ndarray]:
        """Sub-pixel edge contours of the image at the current thresholds, cut where edges
        were erased (what PICK_CONTOUR chooses from)."""
        if self._image is None:
            return []
        if self._contours is None:
            self._contours = find_edge_contours(np.asarray(self._image, dtype=np.float32), *self._thresholds)
        erased = self._erased.get(self._image_key)
        if erased is None or not erased.any():
            return [c for c in self._contours if len(c) >= 3]
        pieces = []
        for contour in self._contours:
            pieces.extend(p for p in oe.split_at_mask(contour, erased) if len(p) >= 3)
        return pieces
