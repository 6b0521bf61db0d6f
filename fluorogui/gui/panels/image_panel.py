"""One fluoroscopic view: the image, its Canny edges, the components' outlines and the
projected model outlines, with the tools that review and edit an outline.

Scene coordinates are pixel coordinates (u, v) = (column, row) with the origin at the
centre of the top-left pixel (the image item is offset by -0.5, -0.5), so a point of an
outline is drawn at its own (u, v). The geometry of every edit lives in
``fluorogui.core.outlines.editing``; this widget turns mouse gestures into those calls and
every outline or edge edit into one undoable step.

The panel is a ``QGraphicsView`` that owns two plain objects: its ``EdgeLayer`` (``edges``:
the Canny edges and the erased pixels) and its ``PanelInteraction`` (``tools``: the mouse
and keyboard gestures), which uses the panel only through ``PanelSurface``.

In the app an edit goes to ``edit_sink(text, (key, points) or None, steps)``: the session
stores the outline under the *key* it was made for (frame, view, component), so undoing
after the panel has moved on to another frame changes the right outline, and the panel
shows it when the app tells it to (``set_outline``); ``steps`` are (do, undo) pairs of the
panel's own state (erased edges) that belong to the same step. A standalone panel (no
sink) pushes its edits onto its own ``undo_stack`` instead.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import (
    QColor,
    QFont,
    QFontMetrics,
    QImage,
    QPainter,
    QPainterPath,
    QPixmap,
    QUndoStack,
)
from PySide6.QtWidgets import (
    QFrame,
    QGraphicsItem,
    QGraphicsPixmapItem,
    QGraphicsScene,
    QGraphicsView,
)

from fluorogui.core.outlines import editing as oe
from fluorogui.core.outlines.spline import OutlineSpline
from fluorogui.gui.panels.image_edges import EdgeLayer
from fluorogui.gui.panels.image_items import (
    BACKGROUND,
    DEFAULT_COLOURS,
    EXTRA_COLOURS,
    FLAGGED_COLOUR,
    MAX_SCALE,
    MIN_SCALE,
    PICK_TOLERANCE_PX,
    AnonymousImage,
    ComponentItems,
    CrossItem,
    EditCommand,
    Tool,
    add_spline_runs,
    cosmetic_pen,
    distance_colours,
    draw_label,
    polygon,
    quantise,
)
from fluorogui.gui.panels.image_tools import PanelInteraction


# -- the panel ------------------------------------------------------------------------------------------
class ImagePanel(QGraphicsView):
    """Zoomable image view of one fluoroscope with edges, outlines and outline tools."""

    window_level_changed = Signal(float, float)
    cursor_moved = Signal(float, float, float)
    point_clicked = Signal(int, float, float)
    outline_edited = Signal(object, str)
    tool_changed = Signal(object)
    #: an outline tool was used where the active component has no outline: (tool, component)
    nothing_to_edit = Signal(object, str)

    def __init__(self, view_index: int, undo_stack: QUndoStack | None = None, parent=None):
        super().__init__(parent)
        self.view_index = int(view_index)
        self.title = f"View {self.view_index + 1}"
        self.undo_stack = undo_stack if undo_stack is not None else QUndoStack(self)
        #: edit_sink(text, (key, points or None) or None, [(do, undo), ...]); None: use undo_stack
        self.edit_sink: Callable[[str, tuple | None, list], None] | None = None
        self.pick_tolerance_px = PICK_TOLERANCE_PX

        self._scene = QGraphicsScene(self)
        self.setScene(self._scene)
        self.setBackgroundBrush(BACKGROUND)
        self.setFrameShape(QFrame.Shape.NoFrame)
        self.setRenderHints(QPainter.RenderHint.Antialiasing | QPainter.RenderHint.SmoothPixmapTransform)
        self.setViewportUpdateMode(QGraphicsView.ViewportUpdateMode.FullViewportUpdate)
        self.setTransformationAnchor(QGraphicsView.ViewportAnchor.NoAnchor)
        self.setResizeAnchor(QGraphicsView.ViewportAnchor.AnchorViewCenter)
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setVerticalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setMouseTracking(True)
        self.viewport().setMouseTracking(True)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setMinimumSize(200, 200)
        self.setAccessibleName(self.title)
        #: drawn in the middle while there is no image (what to do next)
        self.placeholder = ""

        # image and window / level
        self._image: np.ndarray | None = None
        self._image_key = None
        self._index: np.ndarray | None = None  # image quantised to LUT indices
        self._index_values: np.ndarray | None = None  # the image value of each index
        self._window, self._level = 1.0, 0.5
        self._image_item = QGraphicsPixmapItem()
        self._image_item.setOffset(-0.5, -0.5)
        self._image_item.setZValue(0)
        self._image_item.setShapeMode(QGraphicsPixmapItem.ShapeMode.BoundingRectShape)
        self._image_item.setTransformationMode(Qt.TransformationMode.SmoothTransformation)
        # the scaled image is cached at screen resolution, so overlay updates only blit it
        self._image_item.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        self._scene.addItem(self._image_item)

        # outlines
        self._components: dict[str, ComponentItems] = {}
        self._active: str | None = None

        #: the Canny edges and erased pixels of the image; the mouse and keyboard gestures
        self.edges = EdgeLayer(self._scene, self.viewport().update)
        self.tools = PanelInteraction(self, self._scene, self.edges)
        self._place = CrossItem()
        self._place.setZValue(12)
        self._place.setVisible(False)
        self._scene.addItem(self._place)

        self._fitted = True
        self._image_rect = QRectF(-0.5, -0.5, 512, 512)
        self._scene.setSceneRect(self._image_rect.adjusted(-1024, -1024, 1024, 1024))

    def set_title(self, title: str) -> None:
        """The label drawn in the top-left corner (default "View <view_index + 1>")."""
        self.title = str(title)
        self.setAccessibleName(self.title)
        self.viewport().update()

    # -- image ---------------------------------------------------------------------------------------
    def set_image(self, image: np.ndarray | None, key=None) -> None:
        """Show a 2-D image of any dtype (None clears it), windowed automatically from its
        1st and 99.5th percentiles. ``key`` (hashable) names the image so its erased-edge
        mask is kept while other images are shown."""
        self.tools.cancel()
        if image is None:
            self._image = self._index = self._index_values = None
            self._image_key = None
            self._image_item.setPixmap(QPixmap())
            self.edges.show_image(None)
            self.viewport().update()
            return
        arr = np.asarray(image)
        if arr.ndim != 2 or arr.size == 0:
            raise ValueError(f"an image must be a non-empty 2-D array, got shape {arr.shape}")
        old_shape = None if self._image is None else self._image.shape
        self._image = arr
        if key is None:
            self.edges.forget([k for k in self.edges.erased_keys() if isinstance(k, AnonymousImage)])
            key = AnonymousImage()
        self._image_key = key
        self._index, self._index_values = quantise(arr)
        stride = max(1, int(np.sqrt(arr.size / 250_000)))  # percentiles of a regular subsample: fast
        sample = arr[::stride, ::stride]
        finite = sample[np.isfinite(sample)] if arr.dtype.kind == "f" else sample.ravel()
        lo, hi = (np.percentile(finite, [1.0, 99.5]) if finite.size else (0.0, 1.0))
        if not hi > lo:
            lo, hi = float(np.min(finite)) if finite.size else 0.0, (float(np.max(finite)) if finite.size else 1.0)
            if not hi > lo:
                hi = lo + 1.0
        h, w = arr.shape
        self._image_rect = QRectF(-0.5, -0.5, w, h)
        self._scene.setSceneRect(self._image_rect.adjusted(-2 * w, -2 * h, 2 * w, 2 * h))
        self._window, self._level = float(hi - lo), float(lo + hi) / 2.0
        self._render_image()
        self.window_level_changed.emit(self._window, self._level)
        self.edges.show_image(arr, key)
        if old_shape != arr.shape:
            self.fit()

    def forget_images(self) -> None:
        """Another session: drop the image, the edges erased in any image and the zoom, so
        the next image is shown whole (an image of the same size used to keep the zoom)."""
        self.edges.forget()
        self.set_image(None)

    def image(self) -> np.ndarray | None:
        return self._image

    def image_key(self):
        return self._image_key

    def _render_image(self) -> None:
        if self._index is None:
            return
        low = self._level - self._window / 2.0
        lut = np.clip((self._index_values - low) * (255.0 / self._window) + 0.5, 0, 255).astype(np.uint8)
        grey = np.ascontiguousarray(lut[self._index])
        h, w = grey.shape
        qimage = QImage(grey.data, w, h, w, QImage.Format.Format_Grayscale8)
        self._image_item.setPixmap(QPixmap.fromImage(qimage))  # copies the pixels
        self.viewport().update()

    def displayed_image(self) -> QImage:
        """The windowed 8-bit image as shown."""
        return self._image_item.pixmap().toImage()

    def set_window_level(self, window: float, level: float) -> None:
        window = max(float(window), 1e-12)
        level = float(level)
        if (window, level) == (self._window, self._level):
            return
        self._window, self._level = window, level
        self._render_image()
        self.window_level_changed.emit(window, level)

    def window_level(self) -> tuple[float, float]:
        return self._window, self._level

    def value_at(self, u: float, v: float) -> float:
        """Image value at the pixel holding (u, v), NaN outside the image."""
        if self._image is None:
            return float("nan")
        col, row = int(np.floor(u + 0.5)), int(np.floor(v + 0.5))
        h, w = self._image.shape
        if 0 <= row < h and 0 <= col < w:
            return float(self._image[row, col])
        return float("nan")

    # -- view transform --------------------------------------------------------------------------------
    def scale_factor(self) -> float:
        """Screen pixels per image pixel."""
        return float(self.transform().m11())

    def fit(self) -> None:
        """Show the whole image."""
        self.fitInView(self._image_rect, Qt.AspectRatioMode.KeepAspectRatio)
        self._fitted = True
        self._after_transform()

    def zoom_at(self, factor: float, viewport_pos: QPointF | None = None) -> None:
        """Zoom by ``factor`` keeping the scene point under ``viewport_pos`` (default: the
        viewport centre) where it is."""
        if viewport_pos is None:
            viewport_pos = QPointF(self.viewport().rect().center())
        viewport_pos = QPointF(viewport_pos)
        scale = self.scale_factor()
        factor = float(np.clip(scale * factor, MIN_SCALE, MAX_SCALE) / scale)
        if factor == 1.0:
            return
        anchor = self.to_scene(viewport_pos)
        self.scale(factor, factor)
        moved = self.viewportTransform().map(anchor) - viewport_pos
        self.horizontalScrollBar().setValue(self.horizontalScrollBar().value() + round(moved.x()))
        self.verticalScrollBar().setValue(self.verticalScrollBar().value() + round(moved.y()))
        self._fitted = False
        self._after_transform()

    def pan(self, dx: float, dy: float) -> None:
        """Move the view by (dx, dy) screen pixels (a drag)."""
        self.horizontalScrollBar().setValue(self.horizontalScrollBar().value() - round(dx))
        self.verticalScrollBar().setValue(self.verticalScrollBar().value() - round(dy))
        self._fitted = False

    def _after_transform(self) -> None:
        scale = self.scale_factor()
        for comp in self._components.values():
            comp.dots.set_pixel_scale(scale)
            comp.model_dots.set_pixel_scale(scale)
        self.tools.set_pixel_scale(scale)
        mode = Qt.TransformationMode.SmoothTransformation if scale < 1.0 else Qt.TransformationMode.FastTransformation
        self._image_item.setTransformationMode(mode)
        self.edges.set_transformation_mode(mode)
        self.viewport().update()

    def to_scene(self, pos) -> QPointF:
        """Scene point (u, v) under a viewport position, at sub-pixel precision."""
        inverse, _ = self.viewportTransform().inverted()
        return inverse.map(QPointF(pos))

    def tolerance(self) -> float:
        """The click tolerance in image pixels."""
        return self.pick_tolerance_px / max(self.scale_factor(), 1e-6)

    # -- components and outlines ---------------------------------------------------------------------------
    def _component(self, component: str) -> ComponentItems:
        comp = self._components.get(component)
        if comp is None:
            colour = DEFAULT_COLOURS.get(component)
            if colour is None:
                colour = EXTRA_COLOURS[sum(c not in DEFAULT_COLOURS for c in self._components) % len(EXTRA_COLOURS)]
            comp = self._components[component] = ComponentItems(self._scene, colour)
            comp.dots.set_pixel_scale(self.scale_factor())
            comp.model_dots.set_pixel_scale(self.scale_factor())
            self._style_component(component)
        return comp

    def components(self) -> list[str]:
        return list(self._components)

    def set_component_colour(self, component: str, colour: QColor) -> None:
        comp = self._component(component)
        comp.colour = QColor(colour)
        self._style_component(component)

    def component_colour(self, component: str) -> QColor:
        return QColor(self._component(component).colour)

    def set_active_component(self, component: str | None) -> None:
        """The component whose outline the tools edit (None: no editing)."""
        self.tools.cancel()
        self.tools.select(None)
        self._active = component
        if component is not None:
            self._component(component)
        for name in self._components:
            self._style_component(name)
        self.tools.update_highlight()
        self.viewport().update()

    def active_component(self) -> str | None:
        return self._active

    def _style_component(self, component: str) -> None:
        comp = self._components[component]
        active = component == self._active
        line = QColor(comp.colour)
        if not active:
            line.setAlpha(170)
        comp.spline.setPen(cosmetic_pen(line, 2.2 if active else 1.5))
        gap = QColor(comp.colour)
        gap.setAlpha(150)
        comp.gap_line.setPen(cosmetic_pen(gap, 1.0, Qt.PenStyle.DashLine))
        comp.dots.set_style(size_px=5.0 if active else 3.0, colour=comp.colour, halo=active)
        if comp.flagged:  # a pose that needs review: a red dashed outline on top, never the matched look
            comp.model_line.setPen(cosmetic_pen(FLAGGED_COLOUR, 2.2, Qt.PenStyle.DashLine))
            comp.model_line.setZValue(6.5)
            comp.model_dots.set_style(colour=FLAGGED_COLOUR)
        else:
            comp.model_line.setPen(cosmetic_pen(QColor(255, 255, 255, 80), 1.0))
            comp.model_line.setZValue(2)
            # the model outline takes a light tint of its component's colour unless coloured by distance
            comp.model_dots.set_style(colour=QColor(comp.colour).lighter(135))

    def set_outline(self, component: str, points: np.ndarray | None, key=None) -> None:
        """Show a component's outline (closed, (K, 2) of (u, v); None or empty clears it)
        with its spline; ``key`` names the outline (it is handed back to ``edit_sink``)."""
        comp = self._component(component)
        other = key != comp.key and component == self._active  # another frame's outline: no stale marker
        comp.key = key
        if self._active is None:
            self._active = component
            self._style_component(component)
        self.tools.leave_outline(component, forget_marks=other)
        self.display_outline(component, points)
        if component == self._active:
            self.tools.clamp_marks(0 if comp.points is None else len(comp.points))

    def outline(self, component: str) -> np.ndarray | None:
        """The outline shown for a component (a copy), None if there is none."""
        comp = self._components.get(component)
        return None if comp is None or comp.points is None else comp.points.copy()

    def outline_key(self, component: str):
        comp = self._components.get(component)
        return None if comp is None else comp.key

    def spline_ok(self, component: str) -> bool:
        """Whether the shown outline has a valid spline (else its polyline is drawn)."""
        comp = self._components.get(component)
        return bool(comp is not None and comp.spline_ok)

    def display_outline(self, component: str, points) -> None:
        """Draw an outline (points and spline) without touching its key."""
        comp = self._component(component)
        pts = None if points is None else oe.as_points(points)
        if pts is not None and len(pts) == 0:
            pts = None
        comp.points = pts
        comp.dots.set_points(pts)
        path, gap_path = QPainterPath(), QPainterPath()
        comp.spline_ok = False
        comp.gap_count = 0
        if pts is not None and len(pts) >= 2:
            spline = None
            if len(pts) >= 4:
                try:
                    spline = OutlineSpline.fit(pts)
                    comp.spline_ok = True
                except Exception:  # noqa: BLE001 - an unusable outline is shown as its polyline
                    spline = None
            if spline is None:
                path.addPolygon(polygon(pts))
                path.closeSubpath()
            else:
                comp.gap_count = add_spline_runs(path, gap_path, spline)
        comp.spline.setPath(path)
        comp.gap_line.setPath(gap_path)
        self._style_component(component)
        self.viewport().update()

    # -- recording edits -----------------------------------------------------------------------------------
    def record_edit(self, text: str, component: str | None = None, before=None, after=None, steps=()) -> None:
        """One undoable edit: ``component``'s outline from ``before`` to ``after`` (when a
        component is given) together with ``steps``, (do, undo) pairs of the panel's own
        state (erased edges). It goes to ``edit_sink`` when there is one (the app: the
        session stores the outline and the panel shows it when told), else onto the
        panel's own ``undo_stack``."""
        steps = list(steps)
        key = None
        if component is not None:
            key = self._components[component].key
            before = None if before is None or len(before) == 0 else oe.as_points(before)
            after = None if after is None or len(after) == 0 else oe.as_points(after)
        if self.edit_sink is not None and (component is None or key is not None):
            self.edit_sink(text, None if component is None else (key, after), steps)
            if component is not None:
                self.outline_edited.emit(key, component)
            return
        if component is not None:
            steps.append((lambda: self._apply_outline(key, component, after),
                          lambda: self._apply_outline(key, component, before)))
        self.undo_stack.push(EditCommand(text, steps))

    def _apply_outline(self, key, component: str, points: np.ndarray | None) -> None:
        """Show an outline again (a standalone panel's undo and redo)."""
        self.set_outline(component, None if points is None else points.copy(), key)
        self.outline_edited.emit(key, component)

    # -- projected model outline -------------------------------------------------------------------------
    def set_model_outline(self, component: str, points_px: np.ndarray | None,
                          distances_px: np.ndarray | None = None) -> None:
        """Show the projected model outline points of a component, coloured by their
        distance (px) to the image outline when given. Cheap: only updates existing items."""
        comp = self._component(component)
        pts = None if points_px is None else oe.as_points(points_px)
        if pts is not None and len(pts) == 0:
            pts = None
        rgb = None
        if pts is not None and distances_px is not None:
            d = np.asarray(distances_px, dtype=float).reshape(-1)
            if len(d) != len(pts):
                raise ValueError("one distance per model outline point is needed")
            rgb = distance_colours(d)
            comp.model_distances = d.copy()
        else:
            comp.model_distances = None
        comp.model_points = pts
        comp.model_dots.set_points(pts, rgb)
        path = QPainterPath()
        if pts is not None and len(pts) >= 2:
            path.addPolygon(polygon(pts))
            path.closeSubpath()
        comp.model_line.setPath(path)
        self.viewport().update()

    def set_model_flagged(self, component: str, flagged: bool) -> None:
        """Draw a component's model outline as needing review (red, dashed) or not."""
        comp = self._component(component)
        if comp.flagged != bool(flagged):
            comp.flagged = bool(flagged)
            self._style_component(component)
            self.viewport().update()

    def model_flagged(self, component: str) -> bool:
        comp = self._components.get(component)
        return bool(comp is not None and comp.flagged)

    def model_outline(self, component: str) -> np.ndarray | None:
        comp = self._components.get(component)
        return None if comp is None or comp.model_points is None else comp.model_points.copy()

    def model_outline_colours(self, component: str) -> list[QColor]:
        """The colour of each projected model outline point as drawn."""
        comp = self._components.get(component)
        return [] if comp is None else comp.model_dots.colours()

    # -- place marker ----------------------------------------------------------------------------------------
    def set_place_marker(self, u: float, v: float) -> None:
        self._place.setPos(QPointF(float(u), float(v)))
        self._place.setVisible(True)

    def clear_place_marker(self) -> None:
        self._place.setVisible(False)

    def place_marker(self) -> tuple[float, float] | None:
        return (self._place.pos().x(), self._place.pos().y()) if self._place.isVisible() else None

    # -- overlay text ------------------------------------------------------------------------------------------
    def drawForeground(self, painter: QPainter, rect: QRectF) -> None:  # noqa: N802 (Qt override)
        painter.save()
        painter.resetTransform()
        painter.setRenderHint(QPainter.RenderHint.Antialiasing, True)
        font = QFont(self.font())
        font.setPointSizeF(max(font.pointSizeF(), 9.0))
        font.setBold(True)
        draw_label(painter, font, QPointF(8, 8), [(None, self.title)])
        font.setBold(False)
        if self._image is None and self.placeholder:
            fm = QFontMetrics(font)
            lines = self.placeholder.splitlines()
            width = max(fm.horizontalAdvance(line) for line in lines) + 30
            corner = QPointF(max(8.0, (self.viewport().width() - width) / 2), self.viewport().height() / 2 - 30)
            draw_label(painter, font, corner, [(None, line) for line in lines])
        legend = [(self._components[n].colour, n + ("  ✎" if n == self._active else "")
                   + ("  (no spline)" if self._components[n].points is not None and not self._components[n].spline_ok
                      else "") + ("  — needs review" if self._components[n].flagged else ""))
                  for n in self._components if self._components[n].points is not None
                  or self._components[n].model_points is not None or n == self._active]
        if legend:
            fm = QFontMetrics(font)
            width = max(fm.horizontalAdvance(text) for _, text in legend) + 30
            draw_label(painter, font, QPointF(self.viewport().width() - width - 8, 8), legend)
        tool = self.tools.tool()
        if tool != Tool.NAVIGATE:
            text = tool.value + (f"  (brush {self.tools.brush_radius():g} px)" if tool == Tool.ERASE else "")
            fm = QFontMetrics(font)
            draw_label(painter, font, QPointF(8, self.viewport().height() - fm.height() - 16), [(None, text)])
        painter.restore()

    # -- the tools and the edges (the panel's own objects) ------------------------------------------------------
    def set_tool(self, tool: Tool) -> None:
        self.tools.set_tool(tool)

    def tool(self) -> Tool:
        return self.tools.tool()

    def set_brush_radius(self, radius_px: float) -> None:
        """Radius (image pixels) of the ERASE brush."""
        self.tools.set_brush_radius(radius_px)

    def brush_radius(self) -> float:
        return self.tools.brush_radius()

    def selected_point(self) -> int | None:
        return self.tools.selected_point()

    def set_edges_visible(self, visible: bool) -> None:
        self.edges.set_visible(visible)

    def edges_visible(self) -> bool:
        return self.edges.visible()

    def set_canny_thresholds(self, low: float, high: float) -> None:
        """Canny thresholds as fractions of the reference gradient (see core.outlines.edges)."""
        self.edges.set_thresholds(low, high)

    def canny_thresholds(self) -> tuple[float, float]:
        return self.edges.thresholds()

    def erased_mask(self, key=None) -> np.ndarray | None:
        """The erased-edge mask of the image ``key`` (default: the current one); a copy."""
        return self.edges.erased_mask(key)

    def edge_mask(self) -> np.ndarray | None:
        """The edges as shown: Canny edges minus erased pixels (None without an image)."""
        return self.edges.mask()

    def edge_contours(self) -> list[np.ndarray]:
        """Sub-pixel edge contours of the image, cut where edges were erased."""
        return self.edges.contours()

    # -- Qt events: the gestures are the tools' ----------------------------------------------------------------
    def mousePressEvent(self, event) -> None:  # noqa: N802 (Qt override)
        if not self.tools.mouse_press(event):
            super().mousePressEvent(event)

    def mouseMoveEvent(self, event) -> None:  # noqa: N802 (Qt override)
        self.tools.mouse_move(event)

    def mouseReleaseEvent(self, event) -> None:  # noqa: N802 (Qt override)
        self.tools.mouse_release(event)

    def wheelEvent(self, event) -> None:  # noqa: N802 (Qt override)
        self.tools.wheel(event)

    def keyPressEvent(self, event) -> None:  # noqa: N802 (Qt override)
        if not self.tools.key_press(event):
            super().keyPressEvent(event)

    def leaveEvent(self, event) -> None:  # noqa: N802 (Qt override)
        self.tools.leave()
        super().leaveEvent(event)

    def resizeEvent(self, event) -> None:  # noqa: N802 (Qt override)
        super().resizeEvent(event)
        if self._fitted:
            self.fit()
