"""Pure outline-editing operations: exact results on small hand-made outlines."""
import numpy as np
import pytest

from fluorogui.core.outlines.editing import (
    close_gap,
    delete_points,
    erase_in_disc,
    insert_point,
    join_contours,
    move_point,
    nearest_point,
    nearest_segment,
    outline_spacing,
    pick_contour,
    points_in_polygon,
    points_near_path,
    polyline_distance,
    split_at_mask,
    stroke_pixels,
)

SQUARE = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])


def square_outline(side=10):
    """Closed square outline with one point per pixel of perimeter, clockwise on screen."""
    bottom = [(x, 0.0) for x in range(side)]
    right = [(side, float(y)) for y in range(side)]
    top = [(float(x), side) for x in range(side, 0, -1)]
    left = [(0.0, float(y)) for y in range(side, 0, -1)]
    return np.array(bottom + right + top + left, dtype=float)


def three_sides(side=10):
    """The square without its left side: an outline taken from an open contour."""
    bottom = [(float(x), 0.0) for x in range(side + 1)]
    right = [(float(side), float(y)) for y in range(1, side + 1)]
    top = [(float(x), float(side)) for x in range(side - 1, -1, -1)]
    return np.array(bottom + right + top)


def test_nearest_point_and_segment():
    assert nearest_point(SQUARE, (9, 1)) == (1, pytest.approx(np.sqrt(2)))
    assert nearest_segment(SQUARE, (5, -2)) == (0, 0.5, 2.0)
    # the closing segment runs from the last point back to the first
    assert nearest_segment(SQUARE, (-1, 5)) == (3, 0.5, 1.0)
    with pytest.raises(ValueError):
        nearest_point(np.zeros((0, 2)), (0, 0))


def test_move_insert_delete_return_new_arrays():
    before = SQUARE.copy()
    moved = move_point(SQUARE, 2, (12, 11))
    np.testing.assert_array_equal(moved[2], [12, 11])
    np.testing.assert_array_equal(SQUARE, before)

    inserted = insert_point(SQUARE, (5, -1))
    np.testing.assert_array_equal(inserted, [[0, 0], [5, -1], [10, 0], [10, 10], [0, 10]])
    closing = insert_point(SQUARE, (-1, 5))  # into the closing segment: appended
    np.testing.assert_array_equal(closing, [[0, 0], [10, 0], [10, 10], [0, 10], [-1, 5]])

    np.testing.assert_array_equal(delete_points(SQUARE, [0, 2]), [[10, 0], [0, 10]])
    np.testing.assert_array_equal(delete_points(SQUARE, [2, 2, 0]), [[10, 0], [0, 10]])
    np.testing.assert_array_equal(delete_points(SQUARE, np.array([False, True, False, False])),
                                  [[0, 0], [10, 10], [0, 10]])
    with pytest.raises(IndexError):
        delete_points(SQUARE, [4])
    np.testing.assert_array_equal(SQUARE, before)


def test_points_in_polygon_even_odd_and_concave():
    triangle = [(0, 0), (10, 0), (0, 10)]
    pts = np.array([[1, 1], [4, 4], [20, 20], [9, 2], [-1, 1]], dtype=float)
    assert points_in_polygon(pts, triangle).tolist() == [True, True, False, False, False]
    # a U-shaped lasso: the notch between its arms is outside
    u_shape = [(0, 0), (9, 0), (9, 9), (6, 9), (6, 3), (3, 3), (3, 9), (0, 9)]
    pts = np.array([[1.5, 5], [4.5, 5], [7.5, 5], [4.5, 1.5]])
    assert points_in_polygon(pts, u_shape).tolist() == [True, False, True, True]
    assert not points_in_polygon(pts, [(0, 0), (9, 9)]).any()  # not a polygon


def test_erase_in_disc_on_masks_and_points():
    mask = np.ones((5, 5), dtype=bool)
    out = erase_in_disc(mask, (2, 2), 1.0)
    assert mask.all()  # input untouched
    assert out.sum() == 20  # the centre and its four neighbours
    assert not out[2, 2] and not out[1, 2] and not out[2, 3] and out[1, 1]
    assert erase_in_disc(mask, (2, 2), 1.5).sum() == 16  # the 3 x 3 block
    # (u, v) = (column, row): a disc at u = 4, v = 0 clears the top-right corner
    corner = erase_in_disc(mask, (4, 0), 0.5)
    assert not corner[0, 4] and corner[4, 0] and corner.sum() == 24

    kept = erase_in_disc(SQUARE, (10, 10), 1.0)
    np.testing.assert_array_equal(kept, [[0, 0], [10, 0], [0, 10]])


def test_brush_strokes_cover_capsules():
    mask = stroke_pixels((5, 10), [(1, 2), (8, 2)], 0.5)
    assert mask.sum() == 8 and mask[2, 1:9].all()
    wide = stroke_pixels((5, 10), [(1, 2), (8, 2)], 1.0)
    assert wide.sum() == 8 * 3 + 2  # three rows plus the two round ends
    assert stroke_pixels((5, 5), [(50, 50)], 2.0).sum() == 0  # outside the image
    near = points_near_path(square_outline(), [(0, 5), (5, 5)], 5.0)
    # the left side (11 points), bottom and top at u = 1..5, and (10, 5) exactly 5 px away
    assert near.sum() == 11 + 5 + 5 + 1 and near[np.all(square_outline() == (10, 5), axis=1)].all()


def test_close_gap_fills_the_gap_of_an_open_outline():
    pts = three_sides()
    assert len(pts) == 31 and outline_spacing(pts) == 1.0
    closed = close_gap(pts, 30, 0)
    np.testing.assert_array_equal(closed[:31], pts)
    np.testing.assert_array_equal(closed[31:], [[0.0, y] for y in range(9, 0, -1)])
    # the click order does not matter
    np.testing.assert_array_equal(close_gap(pts, 0, 30), closed)
    coarse = close_gap(pts, 30, 0, spacing_px=2.5)
    np.testing.assert_allclose(coarse[31:], [[0, 7.5], [0, 5.0], [0, 2.5]])


def test_close_gap_cuts_off_a_spike():
    square = square_outline()
    spiked = square.copy()
    spiked[4] = (4.0, -3.0)
    np.testing.assert_array_equal(close_gap(spiked, 3, 5), square)
    np.testing.assert_array_equal(close_gap(spiked, 5, 3), square)
    # a detour that wraps past the end of the array
    detour = np.vstack([square[:38], [[1.0, -4.0], [3.0, -4.0]], square[38:]])
    repaired = close_gap(detour, 37, 0)
    np.testing.assert_array_equal(repaired, square)
    with pytest.raises(ValueError):
        close_gap(square, 3, 3)


def test_join_contours_connects_nearest_ends():
    a = np.array([[0.0, 0.0], [10.0, 0.0]])
    b = np.array([[10.0, 5.0], [0.0, 5.0]])
    expected = [[0, 0], [10, 0], [10, 5], [0, 5]]
    np.testing.assert_array_equal(join_contours(a, b), expected)
    np.testing.assert_array_equal(join_contours(a, b[::-1]), expected)
    np.testing.assert_array_equal(join_contours(np.zeros((0, 2)), b), b)


def test_pick_contour_takes_the_nearest_within_reach():
    line0 = np.column_stack([np.arange(11.0), np.zeros(11)])
    line1 = np.column_stack([np.arange(11.0), np.full(11, 10.0)])
    contours = [line0, line1]
    assert pick_contour(contours, (5, 3), 5) == 0
    assert pick_contour(contours, (5.5, 6), 5) == 1
    assert pick_contour(contours, (5, 5), 5) == 0  # a tie goes to the first
    assert pick_contour(contours, (5, 30), 5) is None
    assert pick_contour([], (0, 0), 5) is None
    assert polyline_distance(line0, (13, 4)) == 5.0


def test_split_at_mask_cuts_erased_points_and_wraps_closed_contours():
    line = np.column_stack([np.arange(10.0), np.full(10, 2.0)])
    erased = np.zeros((5, 12), dtype=bool)
    erased[2, 4:6] = True
    pieces = split_at_mask(line, erased)
    assert [p[:, 0].tolist() for p in pieces] == [[0, 1, 2, 3], [6, 7, 8, 9]]
    assert len(split_at_mask(line, np.zeros((5, 12), dtype=bool))) == 1

    ring = square_outline(6)  # ends are neighbours: a closed contour
    erased = np.zeros((8, 8), dtype=bool)
    erased[6, 3] = True  # the point (3, 6) on the top side
    (piece,) = split_at_mask(ring, erased)
    assert len(piece) == len(ring) - 1
    np.testing.assert_array_equal(piece[0], [2, 6])  # starts just after the cut
    np.testing.assert_array_equal(piece[-1], [4, 6])
