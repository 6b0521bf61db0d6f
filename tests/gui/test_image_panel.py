"""The image panel: image display, edges, and every outline tool driven by the mouse, with
undo / redo restoring outlines exactly and commands applying to the key they were made for."""
import numpy as np
import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import QPoint, QPointF, Qt  # noqa: E402
from PySide6.QtGui import QColor  # noqa: E402

from fluorogui.core.outlines.editing import points_near_path  # noqa: E402
from fluorogui.gui.panels.image_panel import ImagePanel, Tool  # noqa: E402

SIZE = 200
CENTRE = np.array([100.0, 100.0])


def disc_image(radius=40.0, centre=CENTRE, background=0.6, inside=0.2, square=False):
    v, u = np.mgrid[0:SIZE, 0:SIZE].astype(float)
    image = np.full((SIZE, SIZE), background, dtype=np.float32)
    image[np.hypot(u - centre[0], v - centre[1]) <= radius] = inside
    if square:  # a dark square in the top-left corner as well
        image[15:45, 15:45] = inside
    return image


def circle(n=24, radius=50.0, start=0.0, stop=2 * np.pi):
    th = start + (stop - start) * np.arange(n) / n
    return CENTRE + radius * np.column_stack([np.cos(th), np.sin(th)])


@pytest.fixture
def panel(qtbot):
    widget = ImagePanel(0)
    qtbot.addWidget(widget)
    widget.resize(420, 420)
    widget.show()
    qtbot.waitExposed(widget)
    widget.set_image(disc_image(), key="frame0")
    widget.fit()
    return widget


def at(panel, u, v) -> QPoint:
    return panel.mapFromScene(QPointF(u, v))


def scene(panel, pos: QPoint) -> np.ndarray:
    p = panel.mapToScene(pos)
    return np.array([p.x(), p.y()])


def click(qtbot, panel, u, v, modifier=Qt.KeyboardModifier.NoModifier):
    qtbot.mouseClick(panel.viewport(), Qt.MouseButton.LeftButton, modifier, at(panel, u, v))


def drag(qtbot, panel, path, button=Qt.MouseButton.LeftButton):
    """Press at the first (u, v), move through the others, release at the last."""
    vp = panel.viewport()
    positions = [at(panel, u, v) for u, v in path]
    qtbot.mousePress(vp, button, pos=positions[0])
    for pos in positions[1:]:
        qtbot.mouseMove(vp, pos)
    qtbot.mouseRelease(vp, button, pos=positions[-1])
    return positions


def check_undo_redo(panel, before, after, component="femoral"):
    panel.undo_stack.undo()
    np.testing.assert_array_equal(panel.outline(component), before)
    panel.undo_stack.redo()
    np.testing.assert_array_equal(panel.outline(component), after)


# -- image, view and edges --------------------------------------------------------------------------
def test_image_pixel_centres_sit_at_their_coordinates(panel, qtbot):
    image = np.arange(SIZE * SIZE, dtype=np.float32).reshape(SIZE, SIZE)
    panel.set_image(image)
    readings = []
    panel.cursor_moved.connect(lambda u, v, value: readings.append((u, v, value)))
    for u, v in [(10.3, 20.4), (0.0, 0.0), (199.0, 57.0)]:
        pos = at(panel, u, v)
        qtbot.mouseMove(panel.viewport(), pos)
        su, sv = scene(panel, pos)
        assert readings[-1][:2] == pytest.approx((su, sv))
        assert readings[-1][2] == image[int(round(sv)), int(round(su))]
    assert np.isnan(panel.value_at(-0.6, 5)) and panel.value_at(-0.4, 5) == image[5, 0]
    assert panel.value_at(199.4, 199.4) == image[199, 199]
    grey = panel.displayed_image()
    assert (grey.width(), grey.height()) == (SIZE, SIZE)


def test_auto_window_level_and_window_level_change_the_pixmap(panel, qtbot):
    rng = np.random.default_rng(0)
    image = rng.normal(1000.0, 200.0, (SIZE, SIZE)).clip(0, 4000).astype(np.uint16)
    panel.set_image(image)
    lo, hi = np.percentile(image, [1.0, 99.5])
    assert panel.window_level() == pytest.approx((hi - lo, (hi + lo) / 2))
    before = panel.displayed_image().pixel(50, 60)
    with qtbot.waitSignal(panel.window_level_changed, timeout=1000) as signal:
        panel.set_window_level(100.0, 900.0)
    assert signal.args == [100.0, 900.0]
    assert panel.displayed_image().pixel(50, 60) != before
    # values below the window are black, above it white
    expected = np.clip((image[60, 50] - 850.0) * 255.0 / 100.0 + 0.5, 0, 255).astype(int)
    assert QColor(panel.displayed_image().pixel(50, 60)).red() == expected
    # right-drag to the right widens the window
    window, _ = panel.window_level()
    drag(qtbot, panel, [(100, 100), (130, 100)], button=Qt.MouseButton.RightButton)
    assert panel.window_level()[0] > window


def test_float_images_with_nan_and_8_bit_images_show(panel):
    image = disc_image()
    image[0, 0] = np.nan
    panel.set_image(image)
    assert not panel.displayed_image().isNull()
    panel.set_image((disc_image() * 255).astype(np.uint8))
    assert panel.window_level()[1] == pytest.approx((0.2 * 255 + 0.6 * 255) / 2, abs=1)
    panel.set_image(None)
    assert panel.image() is None and panel.edge_mask() is None


def test_fit_zoom_to_cursor_and_pan(panel, qtbot):
    anchor = at(panel, 60, 70)
    before = scene(panel, anchor)
    panel.zoom_at(3.0, QPointF(anchor))
    assert scene(panel, anchor) == pytest.approx(before, abs=0.5)
    assert panel.scale_factor() == pytest.approx(3.0 * 400 / 200, rel=0.05)
    centre = scene(panel, panel.viewport().rect().center())
    drag(qtbot, panel, [(100, 100), (110, 100)], button=Qt.MouseButton.MiddleButton)
    assert scene(panel, panel.viewport().rect().center())[0] < centre[0]  # dragged right: view moves left
    qtbot.keyClick(panel, Qt.Key.Key_F)
    corner0, corner1 = at(panel, -0.5, -0.5), at(panel, SIZE - 0.5, SIZE - 0.5)
    assert panel.viewport().rect().contains(corner0) and panel.viewport().rect().contains(corner1)


def test_edges_follow_thresholds(panel):
    panel.set_edges_visible(True)
    edges = panel.edge_mask()
    v, u = np.nonzero(edges)
    radius = np.hypot(u - 100, v - 100)
    assert edges.sum() > 200 and np.all(np.abs(radius - 40) < 2)
    faint = disc_image(inside=0.45) + disc_image(radius=20, centre=(160, 40), inside=0.0) - 0.6
    panel.set_image(faint, key="faint")
    panel.set_canny_thresholds(0.05, 0.1)
    many = panel.edge_mask().sum()
    panel.set_canny_thresholds(0.5, 0.9)
    assert panel.canny_thresholds() == (0.5, 0.9)
    assert panel.edge_mask().sum() < many  # the faint disc's edge is gone
    with pytest.raises(ValueError):
        panel.set_canny_thresholds(0.5, 0.1)


# -- tools --------------------------------------------------------------------------------------------
def test_move_point_is_one_undoable_command(panel, qtbot):
    original = circle()
    panel.set_outline("femoral", original, key="k")
    panel.set_tool(Tool.MOVE)
    positions = drag(qtbot, panel, [(150, 100), (153, 103), (156, 106), (158, 110)])
    moved = panel.outline("femoral")
    np.testing.assert_allclose(moved[0], scene(panel, positions[-1]))
    np.testing.assert_array_equal(moved[1:], original[1:])
    assert panel.undo_stack.count() == 1 and panel.undo_stack.undoText() == "Move point"
    check_undo_redo(panel, original, moved)
    # a click without moving selects, and changes nothing
    click(qtbot, panel, *original[3])
    assert panel.selected_point() == 3 and panel.undo_stack.count() == 1


def test_insert_point_into_nearest_segment(panel, qtbot):
    original = circle()
    panel.set_outline("femoral", original, key="k")
    panel.set_tool(Tool.INSERT)
    target = (original[4] + original[5]) / 2 + (1.0, 1.0)
    click(qtbot, panel, *target)
    after = panel.outline("femoral")
    assert len(after) == len(original) + 1
    np.testing.assert_allclose(after[5], scene(panel, at(panel, *target)))
    np.testing.assert_array_equal(np.delete(after, 5, axis=0), original)
    assert panel.undo_stack.undoText() == "Insert point"
    check_undo_redo(panel, original, after)


def test_delete_point_by_click_and_by_key(panel, qtbot):
    original = circle()
    panel.set_outline("femoral", original, key="k")
    panel.set_tool(Tool.DELETE)
    click(qtbot, panel, *(original[7] + 1.0))
    after = panel.outline("femoral")
    np.testing.assert_array_equal(after, np.delete(original, 7, axis=0))
    check_undo_redo(panel, original, after)
    click(qtbot, panel, 100, 100)  # far from every point: nothing happens
    assert panel.undo_stack.count() == 1
    # the Delete key removes the point nearest to the cursor
    qtbot.mouseMove(panel.viewport(), at(panel, *after[0]))
    qtbot.keyClick(panel, Qt.Key.Key_Delete)
    np.testing.assert_array_equal(panel.outline("femoral"), after[1:])
    assert panel.undo_stack.undoText() == "Delete point"


def test_lasso_deletes_points_inside(panel, qtbot):
    original = circle()
    panel.set_outline("femoral", original, key="k")
    panel.set_tool(Tool.LASSO)
    # a box around the points on the right (angles within +-40 degrees)
    drag(qtbot, panel, [(125, 70), (160, 70), (160, 135), (125, 135), (125, 72)])
    inside = (original[:, 0] > 125) & (original[:, 1] > 70) & (original[:, 1] < 135)
    after = panel.outline("femoral")
    np.testing.assert_array_equal(after, original[~inside])
    assert panel.undo_stack.undoText() == f"Delete {inside.sum()} points"
    check_undo_redo(panel, original, after)


def test_close_gap_and_escape(panel, qtbot):
    arc = circle(n=18, start=0.0, stop=1.5 * np.pi)  # three quarters: open at the top right
    panel.set_outline("femoral", arc, key="k")
    panel.set_tool(Tool.CLOSE_GAP)
    click(qtbot, panel, *arc[-1])
    qtbot.keyClick(panel, Qt.Key.Key_Escape)  # cancels the first click
    click(qtbot, panel, *arc[0])
    assert panel.undo_stack.count() == 0
    click(qtbot, panel, *arc[-1])
    click(qtbot, panel, *arc[0])
    after = panel.outline("femoral")
    np.testing.assert_array_equal(after[:18], arc)
    gap = after[18:]
    spacing = np.linalg.norm(arc[1] - arc[0])
    assert len(gap) == round(np.linalg.norm(arc[0] - arc[-1]) / spacing) - 1
    chord, rel = arc[0] - arc[-1], gap - arc[-1]
    np.testing.assert_allclose(rel[:, 0] * chord[1] - rel[:, 1] * chord[0], 0, atol=1e-9)  # on the chord
    assert panel.undo_stack.undoText() == "Close gap"
    check_undo_redo(panel, arc, after)


def test_pick_contour_takes_the_disc_edge_and_shift_joins(panel, qtbot):
    panel.set_image(disc_image(square=True), key="frame1")
    panel.set_outline("femoral", None, key="k")
    panel.set_tool(Tool.PICK_CONTOUR)
    click(qtbot, panel, 140.5, 100.0)
    picked = panel.outline("femoral")
    radius = np.linalg.norm(picked - CENTRE, axis=1)
    assert len(picked) > 150 and abs(radius.mean() - 39.5) < 0.6 and radius.std() < 0.5
    assert panel.spline_ok("femoral") and panel.undo_stack.undoText() == "Pick contour"
    click(qtbot, panel, 80, 10)  # nowhere near an edge
    assert panel.undo_stack.count() == 1
    click(qtbot, panel, 44.5, 30, Qt.KeyboardModifier.ShiftModifier)
    joined = panel.outline("femoral")
    assert panel.undo_stack.undoText() == "Join contour"
    np.testing.assert_array_equal(joined[:len(picked)], picked)
    assert np.all(joined[len(picked):] < 46)  # the square's edge was appended
    panel.undo_stack.undo()
    np.testing.assert_array_equal(panel.outline("femoral"), picked)
    panel.undo_stack.undo()
    assert panel.outline("femoral") is None


def test_erase_removes_edges_and_points_in_one_undo_step(panel, qtbot):
    panel.set_edges_visible(True)
    original = circle(n=48, radius=40.0)
    panel.set_outline("femoral", original, key="k")
    panel.set_tool(Tool.ERASE)
    panel.set_brush_radius(5.0)
    edges_before = panel.edge_mask()
    positions = drag(qtbot, panel, [(140, 90), (140, 100), (140, 110)])
    stroke = [scene(panel, pos) for pos in positions]
    after = panel.outline("femoral")
    hit = points_near_path(original, stroke, 5.0)
    assert 0 < hit.sum() < 6
    np.testing.assert_array_equal(after, original[~hit])
    edges = panel.edge_mask()
    assert edges.sum() < edges_before.sum()
    assert not edges[95:106, 136:145].any() and edges_before[95:106, 136:145].any()
    assert panel.undo_stack.count() == 1 and panel.undo_stack.undoText().startswith("Erase edges and")
    panel.undo_stack.undo()
    np.testing.assert_array_equal(panel.outline("femoral"), original)
    np.testing.assert_array_equal(panel.edge_mask(), edges_before)
    panel.undo_stack.redo()
    np.testing.assert_array_equal(panel.outline("femoral"), after)
    np.testing.assert_array_equal(panel.edge_mask(), edges)
    # the erased mask belongs to its image: another image has its own, and it comes back
    panel.set_image(disc_image(), key="frame9")
    np.testing.assert_array_equal(panel.edge_mask(), edges_before)
    panel.set_image(disc_image(), key="frame0")
    np.testing.assert_array_equal(panel.edge_mask(), edges)
    # erased edges are no longer picked
    assert not any(points_near_path(c, stroke, 3.0).any() for c in panel.edge_contours())


def test_edits_go_to_the_sink_with_the_key_they_were_made_for(panel, qtbot):
    calls = []

    def sink(text, outline, steps):
        for do, _undo in steps:
            do()
        calls.append((text, outline, steps))
        if outline is not None:  # the app stores it and tells the panel to show it
            panel.set_outline("femoral", outline[1], outline[0])

    panel.edit_sink = sink
    edited = []
    panel.outline_edited.connect(lambda key, component: edited.append((key, component)))
    original = circle()
    panel.set_outline("femoral", original, key=("frame0", "view0"))
    panel.set_tool(Tool.DELETE)
    click(qtbot, panel, *original[2])
    text, (key, points), steps = calls[-1]
    assert text == "Delete point" and key == ("frame0", "view0") and len(points) == len(original) - 1
    assert steps == [] and edited == [(("frame0", "view0"), "femoral")]
    assert panel.undo_stack.count() == 0  # the sink keeps the history, not the panel
    # erasing edges only: the panel's own state travels as a (do, undo) step
    panel.set_image(disc_image(), key="frame0")
    panel.set_edges_visible(True)
    panel.set_tool(Tool.ERASE)
    panel.set_brush_radius(4)
    angle = np.radians(7.5)  # between two outline points, across the disc's edge
    stroke = [tuple(CENTRE + r * np.array([np.cos(angle), np.sin(angle)])) for r in (34.0, 46.0)]
    edges_before = panel.edge_mask().copy()
    drag(qtbot, panel, stroke)
    text, outline, steps = calls[-1]
    assert text == "Erase edges" and outline is None and len(steps) == 1
    assert (panel.edge_mask() != edges_before).any()
    steps[0][1]()  # its undo restores the edges
    np.testing.assert_array_equal(panel.edge_mask(), edges_before)


def test_only_the_active_component_is_edited(panel, qtbot):
    femoral, tibial = circle(), circle(radius=30)
    panel.set_outline("femoral", femoral, key="f")
    panel.set_outline("tibial", tibial, key="t")
    panel.set_active_component("tibial")
    panel.set_tool(Tool.DELETE)
    click(qtbot, panel, *tibial[0])
    click(qtbot, panel, *femoral[12])  # a femoral point, but the tibial outline is edited
    np.testing.assert_array_equal(panel.outline("femoral"), femoral)
    assert len(panel.outline("tibial")) == len(tibial) - 1
    assert panel.component_colour("femoral") != panel.component_colour("tibial")
    panel.set_component_colour("tibial", QColor("orange"))
    assert panel.component_colour("tibial") == QColor("orange")


def test_outline_that_cannot_be_splined_is_still_shown(panel):
    bowtie = np.array([[50, 50], [150, 150], [150, 50], [50, 150]], dtype=float)
    panel.set_outline("femoral", bowtie, key="k")
    assert not panel.spline_ok("femoral")
    np.testing.assert_array_equal(panel.outline("femoral"), bowtie)
    panel.set_outline("femoral", circle(), key="k")
    assert panel.spline_ok("femoral")
    panel.set_outline("femoral", np.zeros((0, 2)), key="k")
    assert panel.outline("femoral") is None


def test_model_outline_colours_follow_distance_and_updates_are_cheap(panel):
    points = circle(n=5)
    panel.set_model_outline("femoral", points, np.array([0.0, 0.9, 3.0, 5.0, 12.0]))
    colours = [c.getRgb()[:3] for c in panel.model_outline_colours("femoral")]
    green, yellow, red = colours[0], colours[2], colours[3]
    assert colours[1] == green and colours[4] == red
    assert green[1] > 150 and green[0] < 100  # green
    assert yellow[0] > 200 and yellow[1] > 200 and yellow[2] < 100  # yellow
    assert red[0] > 200 and red[1] < 100  # red
    n_items = len(panel.scene().items())
    for shift in range(5):
        panel.set_model_outline("femoral", points + shift, np.full(5, float(shift)))
    assert len(panel.scene().items()) == n_items
    np.testing.assert_array_equal(panel.model_outline("femoral"), points + 4)
    panel.set_model_outline("femoral", points)
    tint = panel.component_colour("femoral").lighter(135)  # no distances: the component's own tint
    assert all(c == tint for c in panel.model_outline_colours("femoral"))
    panel.set_model_outline("femoral", None)
    assert panel.model_outline("femoral") is None


def test_place_emits_the_clicked_point_and_marks_it(panel, qtbot):
    panel.set_tool(Tool.PLACE)
    pos = at(panel, 77.0, 33.0)
    with qtbot.waitSignal(panel.point_clicked, timeout=1000) as signal:
        qtbot.mouseClick(panel.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    view, u, v = signal.args
    assert view == 0 and (u, v) == pytest.approx(tuple(scene(panel, pos)))
    assert panel.place_marker() == pytest.approx((u, v))
    panel.clear_place_marker()
    assert panel.place_marker() is None


def test_screenshot_draws_title_and_outline(panel):
    panel.set_outline("femoral", circle(), key="k")
    panel.set_edges_visible(True)
    image = panel.grab().toImage()
    # the dark background outside the image and a blue-ish outline pixel on the circle
    corner = QColor(image.pixel(2, image.height() - 2))
    assert max(corner.red(), corner.green(), corner.blue()) < 40
    pos = at(panel, 150, 100)
    dpr = image.devicePixelRatio()
    colour = QColor(image.pixel(int(pos.x() * dpr), int(pos.y() * dpr)))
    assert colour.blue() > colour.red() + 60
