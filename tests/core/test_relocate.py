"""Relocating a component across a jump of frames from the images alone
(``core.search.relocate``): the patch under its projection in the earlier frame, found
again in each view of the later one, triangulates to its new centroid; views that
disagree give no answer."""
import cv2
import numpy as np
import pytest

from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import rotation_matrix, transform_points
from fluorogui.core.search import relocate
from fluorogui.core.search.relocate import image_shift, relocated_centroid, with_centroid
from fluorogui.simulation.phantoms import femoral_component_mesh
from fluorogui.simulation.protocols import dual_orthogonal_views
from fluorogui.simulation.render import render_fluoro

BEFORE = np.array([2.0, 3.0, -4.0, 10.0, 20.0, -30.0])
AFTER = BEFORE + np.array([24.0, -15.0, 11.0, 6.0, -4.0, 5.0])  # 31 mm and about 9 deg on
ELSEWHERE = BEFORE + np.array([-20.0, 25.0, -18.0, 0.0, 0.0, 0.0])


def _centroid(mesh, pose):
    return rotation_matrix(*pose[3:]) @ mesh.centroid + pose[:3]


@pytest.fixture(scope="module")
def scene():
    mesh = prepare_mesh(*femoral_component_mesh())
    views = dual_orthogonal_views()
    images = {}
    for name, pose, seed in (("before", BEFORE, 3), ("after", AFTER, 4), ("elsewhere", ELSEWHERE, 5)):
        world = transform_points(pose, mesh.vertices)
        images[name] = [render_fluoro(v, [(world, mesh.faces)], np.random.default_rng(seed)) for v in views]
    return mesh, views, images


def test_the_new_centroid_is_found_from_the_images(scene):
    mesh, views, images = scene
    found = relocated_centroid(images["before"], images["after"], views, mesh, pose=BEFORE)
    assert found is not None
    miss = np.linalg.norm(found - _centroid(mesh, AFTER))
    # measured 1.97 mm after moving 31 mm and turning 9 deg (the turned patch correlates
    # best a few px off the centroid's shift): a start for a search near it, not a match
    assert miss < 4.0, miss


def test_views_that_disagree_give_no_answer(scene):
    mesh, views, images = scene
    # view 2 shows the component moved elsewhere: its ray misses view 1's (by 29 mm, measured)
    mixed = [images["after"][0], images["elsewhere"][1]]
    assert relocated_centroid(images["before"], mixed, views, mesh, pose=BEFORE) is None


def test_a_component_out_of_the_image_gives_no_shift(scene):
    mesh, views, images = scene
    nowhere = np.zeros(images["before"][0].shape[:2], bool)
    assert image_shift(images["before"][0], images["after"][0], nowhere) is None


def test_with_centroid_moves_but_does_not_turn(scene):
    mesh, _, _ = scene
    target = np.array([10.0, -20.0, 30.0])
    moved = with_centroid(BEFORE, mesh, target)
    assert np.allclose(_centroid(mesh, moved), target)
    assert np.allclose(rotation_matrix(*moved[3:]), rotation_matrix(*BEFORE[3:]))


def test_the_patch_is_cut_where_the_whole_grown_region_puts_it(scene):
    """``image_shift`` grows the region only in its box: the same shift and correlation as
    growing it over the whole image and cutting the patch where its pixels are, for regions
    inside the image, at its borders and in its corner."""
    _, _, images = scene
    before, after = images["before"][0], images["after"][0]
    h, w = before.shape
    margin = relocate.EDGE_MARGIN_PX
    for v0, v1, u0, u1 in ((300, 420, 350, 600), (0, 90, 200, 330), (h - 70, h, w - 120, w), (500, 503, 0, 4)):
        region = np.zeros((h, w), bool)
        region[v0:v1, u0:u1] = True
        region[v0 + 1:v1 - 1:3, u0 + 1:u1 - 1:2] = False  # not a plain box
        grown = cv2.dilate(region.astype(np.uint8), np.ones((2 * margin + 1,) * 2, np.uint8))
        rows, cols = np.nonzero(grown)
        y0, y1, x0, x1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
        scale = min(1.0, relocate.WORK_WIDTH / max(h, w))
        r = int(relocate.REACH * w)
        Y0, Y1, X0, X1 = max(y0 - r, 0), min(y1 + r, h), max(x0 - r, 0), min(x1 + r, w)
        small = [cv2.resize(np.asarray(a, np.float32), None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
                 for a in (before[y0:y1, x0:x1], grown[y0:y1, x0:x1], after[Y0:Y1, X0:X1])]
        found = image_shift(before, after, region)
        if min(small[0].shape) < 3:
            assert found is None
            continue
        score = cv2.matchTemplate(small[2], small[0], cv2.TM_CCOEFF_NORMED, mask=(small[1] > 0.5).astype(np.float32))
        score[~np.isfinite(score)] = -1.0
        _, best, _, (u, v) = cv2.minMaxLoc(score)
        assert np.array_equal(found[0], [u / scale + X0 - x0, v / scale + Y0 - y0]) and found[1] == best
