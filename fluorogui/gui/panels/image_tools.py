"""How the image panel answers the mouse and keyboard: navigation (zoom, pan, window/level)
and the outline tools, each edit one undoable step.

``PanelInteraction`` is a plain object the panel owns and hands its Qt events to. It
keeps the state of a gesture (the tool, the brush, a drag in progress, the selected point
and the first end of a gap) and the items that show it; what it uses of the panel is
listed in code, in ``PanelSurface``, and the edges it edits are the panel's ``EdgeLayer``.
An edit is recorded by ``PanelSurface.record_edit`` (the session's history in the app,
the panel's own undo stack when standalone)."""
from __future__ import annotations

from typing import Protocol

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QColor, QPainterPath
from PySide6.QtWidgets import QGraphicsEllipseItem, QGraphicsPathItem, QGraphicsScene, QWidget

from fluorogui.core.outlines import editing as oe
from fluorogui.gui.panels.image_edges import EdgeLayer
from fluorogui.gui.panels.image_items import HIGHLIGHT, DotsItem, Tool, cosmetic_pen, guarded, polygon

#: the tools that edit points of an existing outline
NEEDS_OUTLINE = (Tool.MOVE, Tool.DELETE, Tool.LASSO, Tool.CLOSE_GAP)


class PanelSurface(Protocol):
    """What the interaction uses of its panel (``ImagePanel``), and nothing else."""

    view_index: int
    cursor_moved: object  # Signal(u, v, value)
    point_clicked: object  # Signal(view, u, v): a click with the Place tool
    tool_changed: object  # Signal(Tool)
    nothing_to_edit: object  # Signal(Tool, component)

    def viewport(self) -> QWidget: ...
    def setFocus(self, reason: Qt.FocusReason) -> None: ...  # noqa: N802 (Qt's name)
    def to_scene(self, pos) -> QPointF: ...
    def tolerance(self) -> float: ...
    def value_at(self, u: float, v: float) -> float: ...
    def window_level(self) -> tuple[float, float]: ...
    def set_window_level(self, window: float, level: float) -> None: ...
    def pan(self, dx: float, dy: float) -> None: ...
    def zoom_at(self, factor: float, viewport_pos: QPointF | None = None) -> None: ...
    def fit(self) -> None: ...
    def set_place_marker(self, u: float, v: float) -> None: ...
    def active_component(self) -> str | None: ...
    def outline(self, component: str) -> np.ndarray | None: ...
    def display_outline(self, component: str, points) -> None: ...
    def record_edit(self, text: str, component: str | None = None, before=None, after=None, steps=()) -> None: ...


class PanelInteraction:
    """Mouse, wheel and keyboard handling of an image panel: navigation and the outline tools."""

    def __init__(self, surface: PanelSurface, scene: QGraphicsScene, edges: EdgeLayer) -> None:
        self.surface = surface
        self.edges = edges
        self._tool = Tool.NAVIGATE
        self._drag: dict | None = None
        self._cursor_scene: QPointF | None = None
        self._selected: int | None = None
        self._gap_first: int | None = None
        self._highlight = DotsItem(12.0, HIGHLIGHT, halo=True)
        self._highlight.setZValue(4.5)
        scene.addItem(self._highlight)
        self._brush_radius = 6.0
        self._brush = QGraphicsEllipseItem()
        self._brush.setPen(cosmetic_pen(QColor(255, 255, 255, 220), 1.2, Qt.PenStyle.DashLine))
        self._brush.setBrush(QColor(255, 255, 255, 30))
        self._brush.setZValue(11)
        self._brush.setVisible(False)
        scene.addItem(self._brush)
        self._lasso_item = QGraphicsPathItem()
        self._lasso_item.setPen(cosmetic_pen(QColor(255, 255, 255, 230), 1.2, Qt.PenStyle.DashLine))
        self._lasso_item.setBrush(QColor(255, 80, 80, 45))
        self._lasso_item.setZValue(10)
        scene.addItem(self._lasso_item)
        self._update_cursor_shape()

    # -- tools -----------------------------------------------------------------------------------------------
    def set_tool(self, tool: Tool) -> None:
        tool = Tool(tool)
        if tool == self._tool:
            return
        self.cancel()
        self._tool = tool
        self._brush.setVisible(False)
        self._update_cursor_shape()
        self.surface.viewport().update()
        self.surface.tool_changed.emit(tool)

    def tool(self) -> Tool:
        return self._tool

    def set_brush_radius(self, radius_px: float) -> None:
        """Radius (image pixels) of the ERASE brush."""
        self._brush_radius = max(float(radius_px), 0.5)
        if self._cursor_scene is not None:
            self._update_brush(self._cursor_scene)
        self.surface.viewport().update()

    def brush_radius(self) -> float:
        return self._brush_radius

    # -- the marked points (the selected one, the first end of a gap) ----------------------------------------------
    def selected_point(self) -> int | None:
        return self._selected

    def select(self, index: int | None) -> None:
        """Mark a point of the active outline as selected (None: none); shown by ``update_highlight``."""
        self._selected = index

    def leave_outline(self, component: str, forget_marks: bool) -> None:
        """A component's outline is about to be replaced: a gesture on it is abandoned and,
        with ``forget_marks`` (another frame's outline), its marked points are dropped."""
        if forget_marks:
            self._selected = self._gap_first = None
        if self._drag is not None and self._drag.get("component") == component:
            self.cancel()

    def clamp_marks(self, count: int) -> None:
        """The active outline now has ``count`` points: marks beyond them are dropped."""
        if self._selected is not None and self._selected >= count:
            self._selected = None
        if self._gap_first is not None and self._gap_first >= count:
            self._gap_first = None
        self.update_highlight()

    def set_pixel_scale(self, scale: float) -> None:
        self._highlight.set_pixel_scale(scale)

    def update_highlight(self) -> None:
        active = self.surface.active_component()
        points = self.surface.outline(active) if active is not None else None
        marked = [i for i in (self._selected, self._gap_first) if i is not None]
        if points is None or not marked:
            self._highlight.set_points(None)
        else:
            self._highlight.set_points(points[[i for i in marked if i < len(points)]])

    def _update_cursor_shape(self) -> None:
        shape = Qt.CursorShape.OpenHandCursor if self._tool == Tool.NAVIGATE else Qt.CursorShape.CrossCursor
        self.surface.viewport().setCursor(shape)

    def _update_brush(self, scene: QPointF) -> None:
        r = self._brush_radius
        self._brush.setRect(QRectF(scene.x() - r, scene.y() - r, 2 * r, 2 * r))
        self._brush.setVisible(self._tool == Tool.ERASE)

    def _active_points(self) -> np.ndarray | None:
        active = self.surface.active_component()
        return None if active is None else self.surface.outline(active)

    def _nearest_within(self, scene: QPointF) -> int | None:
        pts = self._active_points()
        if pts is None or len(pts) == 0:
            return None
        i, d = oe.nearest_point(pts, (scene.x(), scene.y()))
        return i if d <= self.surface.tolerance() else None

    def _record_outline_edit(self, text: str, before, after) -> None:
        self.surface.record_edit(text, self.surface.active_component(), before, after)

    # -- mouse ------------------------------------------------------------------------------------------------------
    @guarded
    def mouse_press(self, event) -> bool:
        """A button pressed in the view; False when it is not ours (the view's default then)."""
        pos = event.position()
        scene = self.surface.to_scene(pos)
        button = event.button()
        self.surface.setFocus(Qt.FocusReason.MouseFocusReason)
        if self._drag is not None:
            event.accept()
            return True
        navigate = button == Qt.MouseButton.LeftButton and self._tool == Tool.NAVIGATE
        if button == Qt.MouseButton.MiddleButton or navigate:
            self._drag = {"kind": "pan", "last": QPointF(pos)}
            self.surface.viewport().setCursor(Qt.CursorShape.ClosedHandCursor)
        elif button == Qt.MouseButton.RightButton:
            window, level = self.surface.window_level()
            self._drag = {"kind": "window", "start": QPointF(pos), "window": window, "level": level}
        elif button == Qt.MouseButton.LeftButton:
            self._press_tool(scene, event.modifiers())
        else:
            return False
        event.accept()
        return True

    @guarded
    def mouse_move(self, event) -> bool:
        pos = event.position()
        scene = self.surface.to_scene(pos)
        self._cursor_scene = scene
        self.surface.cursor_moved.emit(scene.x(), scene.y(), self.surface.value_at(scene.x(), scene.y()))
        if self._tool == Tool.ERASE:
            self._update_brush(scene)
        drag = self._drag
        if drag is None:
            event.accept()
            return True
        kind = drag["kind"]
        if kind == "pan":
            delta = QPointF(pos) - drag["last"]
            drag["last"] = QPointF(pos)
            self.surface.pan(delta.x(), delta.y())
        elif kind == "window":
            delta = QPointF(pos) - drag["start"]
            window = drag["window"] * float(2.0 ** (delta.x() / 150.0))
            level = drag["level"] + delta.y() * drag["window"] / 300.0
            self.surface.set_window_level(window, level)
        elif kind == "move":
            drag["moved"] = True
            current = oe.move_point(drag["before"], drag["index"], (scene.x(), scene.y()))
            self.surface.display_outline(drag["component"], current)
            self.update_highlight()
        elif kind == "erase":
            self._erase_to(drag, scene)
        elif kind == "lasso":
            drag["path"].append((scene.x(), scene.y()))
            self._draw_lasso(drag["path"])
        event.accept()
        return True

    @guarded
    def mouse_release(self, event) -> bool:
        drag = self._drag
        if drag is None:
            event.accept()
            return True
        scene = self.surface.to_scene(event.position())
        self._drag = None
        kind = drag["kind"]
        if kind == "pan":
            self._update_cursor_shape()
        elif kind == "move":
            if drag.get("moved"):
                after = oe.move_point(drag["before"], drag["index"], (scene.x(), scene.y()))
                self.surface.display_outline(drag["component"], after)
                self._record_outline_edit("Move point", drag["before"], after)
        elif kind == "erase":
            self._erase_to(drag, scene)
            self._finish_erase(drag)
        elif kind == "lasso":
            self._lasso_item.setPath(QPainterPath())
            pts = self._active_points()
            inside = oe.points_in_polygon(pts, drag["path"]) if pts is not None else np.zeros(0, bool)
            n = int(inside.sum())
            if n:
                self._selected = None
                self._record_outline_edit(f"Delete {n} point{'s' if n != 1 else ''}", pts,
                                          oe.delete_points(pts, inside))
        event.accept()
        return True

    @guarded
    def wheel(self, event) -> bool:
        delta = event.angleDelta().y() or event.angleDelta().x()
        if delta:
            self.surface.zoom_at(2.0 ** (delta / 480.0), event.position())
        event.accept()
        return True

    def leave(self) -> None:
        """The mouse left the view: no brush outline."""
        self._brush.setVisible(False)

    def _press_tool(self, scene: QPointF, modifiers) -> None:
        p = (scene.x(), scene.y())
        tool = self._tool
        if tool == Tool.PLACE:
            self.surface.set_place_marker(*p)
            self.surface.point_clicked.emit(self.surface.view_index, float(p[0]), float(p[1]))
            return
        active = self.surface.active_component()
        if active is None:
            return
        pts = self._active_points()
        if tool in NEEDS_OUTLINE and (pts is None or len(pts) == 0):
            self.surface.nothing_to_edit.emit(tool, active)  # say so rather than do nothing
            return
        if tool == Tool.PICK_CONTOUR:
            self._pick(p, join=bool(modifiers & Qt.KeyboardModifier.ShiftModifier))
        elif tool == Tool.MOVE:
            i = self._nearest_within(scene)
            self._selected = i
            self.update_highlight()
            if i is not None:
                self._drag = {"kind": "move", "component": active, "index": i, "before": pts.copy(),
                              "moved": False}
        elif tool == Tool.INSERT:
            base = np.zeros((0, 2)) if pts is None else pts
            after = oe.insert_point(base, p)
            self._record_outline_edit("Insert point", pts, after)
            self._selected = oe.nearest_segment(base, p)[0] + 1 if len(base) >= 2 else len(base)
            self.update_highlight()
        elif tool == Tool.DELETE:
            i = self._nearest_within(scene)
            if i is not None:
                self._delete_index(i)
        elif tool == Tool.ERASE:
            edges = self.edges
            shape = None if edges.image is None else edges.image.shape
            self._drag = {
                "kind": "erase", "component": active, "before": None if pts is None else pts.copy(),
                "removed": np.zeros(0 if pts is None else len(pts), dtype=bool), "last": p,
                "image_key": edges.image_key,
                "erased_before": None if shape is None else edges.erased_for(edges.image_key, shape).copy(),
            }
            if shape is not None:
                self._drag["erased"] = self._drag["erased_before"].copy()
            self._erase_to(self._drag, scene)
        elif tool == Tool.LASSO:
            self._drag = {"kind": "lasso", "path": [p]}
            self._draw_lasso([p])
        elif tool == Tool.CLOSE_GAP:
            i = self._nearest_within(scene)
            if i is None:
                return
            if self._gap_first is None or self._gap_first == i:
                self._gap_first = i
            else:
                try:
                    after = oe.close_gap(pts, self._gap_first, i)
                except ValueError:
                    after = None
                self._gap_first = None
                self._selected = None
                if after is not None:
                    self._record_outline_edit("Close gap", pts, after)
            self.update_highlight()

    def _pick(self, p, join: bool) -> None:
        contours = self.edges.contours()
        index = oe.pick_contour(contours, p, self.surface.tolerance())
        if index is None:
            return
        contour = contours[index]
        pts = self._active_points()
        self._selected = None
        self._gap_first = None
        if join and pts is not None and len(pts):
            self._record_outline_edit("Join contour", pts, oe.join_contours(pts, contour))
        else:
            self._record_outline_edit("Pick contour", pts, contour)

    def _delete_index(self, i: int) -> None:
        pts = self._active_points()
        self._selected = None
        self._gap_first = None
        self._record_outline_edit("Delete point", pts, oe.delete_points(pts, [i]))
        self.update_highlight()

    def _erase_to(self, drag: dict, scene: QPointF) -> None:
        """Extend a brush stroke to ``scene`` and show the result live."""
        p = (scene.x(), scene.y())
        segment = [drag["last"], p]
        drag["last"] = p
        if drag["before"] is not None:
            drag["removed"] |= oe.points_near_path(drag["before"], segment, self._brush_radius)
            self.surface.display_outline(drag["component"], oe.delete_points(drag["before"], drag["removed"]))
        if "erased" in drag:
            drag["erased"] |= oe.stroke_pixels(drag["erased"].shape, segment, self._brush_radius)
            self.edges.refresh(erased_override=drag["erased"])

    def _finish_erase(self, drag: dict) -> None:
        steps = []
        parts = []
        edges = self.edges
        if "erased" in drag:
            flat = np.flatnonzero(drag["erased"] & ~drag["erased_before"])
            canny = edges.canny_mask()
            if flat.size:
                key, shape = drag["image_key"], drag["erased"].shape
                steps.append((lambda: edges.set_erased(key, shape, flat, True),
                              lambda: edges.set_erased(key, shape, flat, False)))
                if canny is not None and canny.flat[flat].any():
                    parts.append("edges")
        n = int(drag["removed"].sum())
        after = None
        if n:
            after = oe.delete_points(drag["before"], drag["removed"])
            parts.append(f"{n} point{'s' if n != 1 else ''}")
        if not steps and not n:
            edges.refresh()
            return
        self._selected = None
        self._gap_first = None
        text = "Erase " + (" and ".join(parts) if parts else "edges")
        if n:
            self.surface.record_edit(text, drag["component"], drag["before"], after, steps)
        else:
            self.surface.record_edit(text, steps=steps)

    def _draw_lasso(self, path) -> None:
        qpath = QPainterPath()
        qpath.addPolygon(polygon(np.asarray(path, dtype=float)))
        qpath.closeSubpath()
        self._lasso_item.setPath(qpath)

    def cancel(self) -> None:
        """Abandon a drag in progress (restoring what it showed), a lasso or a half-made gap."""
        drag, self._drag = self._drag, None
        if drag is not None:
            if drag["kind"] in ("move", "erase") and drag.get("before") is not None:
                self.surface.display_outline(drag["component"], drag["before"])
            if drag["kind"] == "erase":
                self.edges.refresh()
            if drag["kind"] == "pan":
                self._update_cursor_shape()
        self._lasso_item.setPath(QPainterPath())
        self._gap_first = None
        self.update_highlight()

    # -- keyboard ------------------------------------------------------------------------------------------------
    @guarded
    def key_press(self, event) -> bool:
        """A key pressed in the view; False when it is not ours (the view's default then)."""
        key = event.key()
        if key == Qt.Key.Key_F and not event.modifiers() & ~Qt.KeyboardModifier.KeypadModifier:
            self.surface.fit()
        elif key in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace):
            i = self._selected
            if i is None and self._cursor_scene is not None:
                i = self._nearest_within(self._cursor_scene)
            pts = self._active_points()
            if i is not None and pts is not None and i < len(pts):
                self._delete_index(i)
        elif key == Qt.Key.Key_Escape:
            self.cancel()
            self._selected = None
            self.update_highlight()
        else:
            return False
        event.accept()
        return True
