"""How the image panel answers the mouse and keyboard: navigation (zoom, pan, window/level)
and the outline tools, each edit one undoable step.

``PanelInteraction`` is a mixin of ``ImagePanel``; it uses the panel's image, outline and
undo state (``_components``, ``_active``, ``undo_stack``, ``edit_sink`` ...). An edit goes
to ``edit_sink`` when the panel has one (the app: the session stores the outline and
the panel shows it when told), else onto the panel's own ``undo_stack``."""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QPainterPath

from fluorogui.core.outlines import editing as oe
from fluorogui.gui.panels.image_items import EditCommand, Tool, guarded, polygon

#: the tools that edit points of an existing outline
NEEDS_OUTLINE = (Tool.MOVE, Tool.DELETE, Tool.LASSO, Tool.CLOSE_GAP)


class PanelInteraction:
    """Mouse, wheel and keyboard handling of ``ImagePanel`` (a mixin)."""

    # -- tools -----------------------------------------------------------------------------------------------
    def set_tool(self, tool: Tool) -> None:
        tool = Tool(tool)
        if tool == self._tool:
            return
        self._cancel_interaction()
        self._tool = tool
        self._brush.setVisible(False)
        self._update_cursor_shape()
        self.viewport().update()
        self.tool_changed.emit(tool)

    def tool(self) -> Tool:
        return self._tool

    def set_brush_radius(self, radius_px: float) -> None:
        """Radius (image pixels) of the ERASE brush."""
        self._brush_radius = max(float(radius_px), 0.5)
        if self._cursor_scene is not None:
            self._update_brush(self._cursor_scene)
        self.viewport().update()

    def brush_radius(self) -> float:
        return self._brush_radius

    def selected_point(self) -> int | None:
        return self._selected

    def _update_cursor_shape(self) -> None:
        shape = Qt.CursorShape.OpenHandCursor if self._tool == Tool.NAVIGATE else Qt.CursorShape.CrossCursor
        self.viewport().setCursor(shape)

    def _update_brush(self, scene: QPointF) -> None:
        r = self._brush_radius
        self._brush.setRect(QRectF(scene.x() - r, scene.y() - r, 2 * r, 2 * r))
        self._brush.setVisible(self._tool == Tool.ERASE)

    def _update_highlight(self) -> None:
        comp = self._components.get(self._active) if self._active is not None else None
        marked = [i for i in (self._selected, self._gap_first) if i is not None]
        if comp is None or comp.points is None or not marked:
            self._highlight.set_points(None)
        else:
            self._highlight.set_points(comp.points[[i for i in marked if i < len(comp.points)]])

    def _active_points(self) -> np.ndarray | None:
        if self._active is None or self._active not in self._components:
            return None
        return self._components[self._active].points

    def _nearest_within(self, scene: QPointF) -> int | None:
        pts = self._active_points()
        if pts is None or len(pts) == 0:
            return None
        i, d = oe.nearest_point(pts, (scene.x(), scene.y()))
        return i if d <= self._tolerance() else None

    # -- commands ------------------------------------------------------------------------------------------------
    def _apply_outline(self, key, component: str, points: np.ndarray | None) -> None:
        """Show an outline again (a standalone panel's undo and redo)."""
        self.set_outline(component, None if points is None else points.copy(), key)
        self.outline_edited.emit(key, component)

    def _push_edit(self, text: str, component: str | None = None, before=None, after=None, steps=()) -> None:
        """One undoable edit: ``component``'s outline from ``before`` to ``after`` (when a
        component is given) together with ``steps``, (do, undo) pairs of the panel's own
        state (erased edges)."""
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

    def _push_outline_edit(self, text: str, before, after) -> None:
        self._push_edit(text, self._active, before, after)

    def _set_erased_pixels(self, key, shape, flat: np.ndarray, value: bool) -> None:
        mask = self._erased_for(key, shape)
        mask.flat[flat] = value
        if key == self._image_key:
            self._refresh_edges()

    # -- mouse ------------------------------------------------------------------------------------------------------
    @guarded
    def mousePressEvent(self, event) -> None:  # noqa: N802 (Qt override)
        pos = event.position()
        scene = self._to_scene(pos)
        button = event.button()
        self.setFocus(Qt.FocusReason.MouseFocusReason)
        if self._drag is not None:
            event.accept()
            return
        navigate = button == Qt.MouseButton.LeftButton and self._tool == Tool.NAVIGATE
        if button == Qt.MouseButton.MiddleButton or navigate:
            self._drag = {"kind": "pan", "last": QPointF(pos)}
            self.viewport().setCursor(Qt.CursorShape.ClosedHandCursor)
        elif button == Qt.MouseButton.RightButton:
            self._drag = {"kind": "window", "start": QPointF(pos), "window": self._window, "level": self._level}
        elif button == Qt.MouseButton.LeftButton:
            self._press_tool(scene, event.modifiers())
        else:
            super().mousePressEvent(event)
            return
        event.accept()

    @guarded
    def mouseMoveEvent(self, event) -> None:  # noqa: N802 (Qt override)
        pos = event.position()
        scene = self._to_scene(pos)
        self._cursor_scene = scene
        self.cursor_moved.emit(scene.x(), scene.y(), self.value_at(scene.x(), scene.y()))
        if self._tool == Tool.ERASE:
            self._update_brush(scene)
        drag = self._drag
        if drag is None:
            event.accept()
            return
        kind = drag["kind"]
        if kind == "pan":
            delta = QPointF(pos) - drag["last"]
            drag["last"] = QPointF(pos)
            self._pan(delta.x(), delta.y())
        elif kind == "window":
            delta = QPointF(pos) - drag["start"]
            window = drag["window"] * float(2.0 ** (delta.x() / 150.0))
            level = drag["level"] + delta.y() * drag["window"] / 300.0
            self.set_window_level(window, level)
        elif kind == "move":
            drag["moved"] = True
            current = oe.move_point(drag["before"], drag["index"], (scene.x(), scene.y()))
            self._display_outline(drag["component"], current)
            self._update_highlight()
        elif kind == "erase":
            self._erase_to(drag, scene)
        elif kind == "lasso":
            drag["path"].append((scene.x(), scene.y()))
            self._draw_lasso(drag["path"])
        event.accept()

    @guarded
    def mouseReleaseEvent(self, event) -> None:  # noqa: N802 (Qt override)
        drag = self._drag
        if drag is None:
            event.accept()
            return
        scene = self._to_scene(event.position())
        self._drag = None
        kind = drag["kind"]
        if kind == "pan":
            self._update_cursor_shape()
        elif kind == "move":
            if drag.get("moved"):
                after = oe.move_point(drag["before"], drag["index"], (scene.x(), scene.y()))
                self._display_outline(drag["component"], after)
                self._push_outline_edit("Move point", drag["before"], after)
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
                self._push_outline_edit(f"Delete {n} point{'s' if n != 1 else ''}", pts, oe.delete_points(pts, inside))
        event.accept()

    @guarded
    def wheelEvent(self, event) -> None:  # noqa: N802 (Qt override)
        delta = event.angleDelta().y() or event.angleDelta().x()
        if delta:
            self.zoom_at(2.0 ** (delta / 480.0), event.position())
        event.accept()

    def leaveEvent(self, event) -> None:  # noqa: N802 (Qt override)
        self._brush.setVisible(False)
        super().leaveEvent(event)

    def resizeEvent(self, event) -> None:  # noqa: N802 (Qt override)
        super().resizeEvent(event)
        if self._fitted:
            self.fit()

    def _press_tool(self, scene: QPointF, modifiers) -> None:
        p = (scene.x(), scene.y())
        tool = self._tool
        if tool == Tool.PLACE:
            self.set_place_marker(*p)
            self.point_clicked.emit(self.view_index, float(p[0]), float(p[1]))
            return
        if self._active is None:
            return
        pts = self._active_points()
        if tool in NEEDS_OUTLINE and (pts is None or len(pts) == 0):
            self.nothing_to_edit.emit(tool, self._active)  # say so rather than do nothing
            return
        if tool == Tool.PICK_CONTOUR:
            self._pick(p, join=bool(modifiers & Qt.KeyboardModifier.ShiftModifier))
        elif tool == Tool.MOVE:
            i = self._nearest_within(scene)
            self._selected = i
            self._update_highlight()
            if i is not None:
                self._drag = {"kind": "move", "component": self._active, "index": i, "before": pts.copy(),
                              "moved": False}
        elif tool == Tool.INSERT:
            base = np.zeros((0, 2)) if pts is None else pts
            after = oe.insert_point(base, p)
            self._push_outline_edit("Insert point", pts, after)
            self._selected = oe.nearest_segment(base, p)[0] + 1 if len(base) >= 2 else len(base)
            self._update_highlight()
        elif tool == Tool.DELETE:
            i = self._nearest_within(scene)
            if i is not None:
                self._delete_index(i)
        elif tool == Tool.ERASE:
            shape = None if self._image is None else self._image.shape
            self._drag = {
                "kind": "erase", "component": self._active, "before": None if pts is None else pts.copy(),
                "removed": np.zeros(0 if pts is None else len(pts), dtype=bool), "last": p,
                "image_key": self._image_key,
                "erased_before": None if shape is None else self._erased_for(self._image_key, shape).copy(),
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
                    self._push_outline_edit("Close gap", pts, after)
            self._update_highlight()

    def _pick(self, p, join: bool) -> None:
        contours = self.edge_contours()
        index = oe.pick_contour(contours, p, self._tolerance())
        if index is None:
            return
        contour = contours[index]
        pts = self._active_points()
        self._selected = None
        self._gap_first = None
        if join and pts is not None and len(pts):
            self._push_outline_edit("Join contour", pts, oe.join_contours(pts, contour))
        else:
            self._push_outline_edit("Pick contour", pts, contour)

    def _delete_index(self, i: int) -> None:
        pts = self._active_points()
        self._selected = None
        self._gap_first = None
        self._push_outline_edit("Delete point", pts, oe.delete_points(pts, [i]))
        self._update_highlight()

    def _erase_to(self, drag: dict, scene: QPointF) -> None:
        """Extend a brush stroke to ``scene`` and show the result live."""
        p = (scene.x(), scene.y())
        segment = [drag["last"], p]
        drag["last"] = p
        if drag["before"] is not None:
            drag["removed"] |= oe.points_near_path(drag["before"], segment, self._brush_radius)
            self._display_outline(drag["component"], oe.delete_points(drag["before"], drag["removed"]))
        if "erased" in drag:
            drag["erased"] |= oe.stroke_pixels(drag["erased"].shape, segment, self._brush_radius)
            self._refresh_edges(erased_override=drag["erased"])

    def _finish_erase(self, drag: dict) -> None:
        steps = []
        parts = []
        if "erased" in drag:
            flat = np.flatnonzero(drag["erased"] & ~drag["erased_before"])
            canny = self._canny_mask()
            if flat.size:
                key, shape = drag["image_key"], drag["erased"].shape
                steps.append((lambda: self._set_erased_pixels(key, shape, flat, True),
                              lambda: self._set_erased_pixels(key, shape, flat, False)))
                if canny is not None and canny.flat[flat].any():
                    parts.append("edges")
        n = int(drag["removed"].sum())
        after = None
        if n:
            after = oe.delete_points(drag["before"], drag["removed"])
            parts.append(f"{n} point{'s' if n != 1 else ''}")
        if not steps and not n:
            self._refresh_edges()
            return
        self._selected = None
        self._gap_first = None
        text = "Erase " + (" and ".join(parts) if parts else "edges")
        if n:
            self._push_edit(text, drag["component"], drag["before"], after, steps)
        else:
            self._push_edit(text, steps=steps)

    def _draw_lasso(self, path) -> None:
        qpath = QPainterPath()
        qpath.addPolygon(polygon(np.asarray(path, dtype=float)))
        qpath.closeSubpath()
        self._lasso_item.setPath(qpath)

    def _cancel_interaction(self) -> None:
        """Abandon a drag in progress (restoring what it showed), a lasso or a half-made gap."""
        drag, self._drag = self._drag, None
        if drag is not None:
            if drag["kind"] in ("move", "erase") and drag.get("before") is not None:
                self._display_outline(drag["component"], drag["before"])
            if drag["kind"] == "erase":
                self._refresh_edges()
            if drag["kind"] == "pan":
                self._update_cursor_shape()
        self._lasso_item.setPath(QPainterPath())
        self._gap_first = None
        self._update_highlight()

    # -- keyboard ------------------------------------------------------------------------------------------------
    @guarded
    def keyPressEvent(self, event) -> None:  # noqa: N802 (Qt override)
        key = event.key()
        if key == Qt.Key.Key_F and not event.modifiers() & ~Qt.KeyboardModifier.KeypadModifier:
            self.fit()
        elif key in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace):
            i = self._selected
            if i is None and self._cursor_scene is not None:
                i = self._nearest_within(self._cursor_scene)
            pts = self._active_points()
            if i is not None and pts is not None and i < len(pts):
                self._delete_index(i)
        elif key == Qt.Key.Key_Escape:
            self._cancel_interaction()
            self._selected = None
            self._update_highlight()
        else:
            super().keyPressEvent(event)
            return
        event.accept()
