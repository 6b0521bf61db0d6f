"""Relocating a component across a jump of frames from the images alone
(``core.search.relocate``): the patch under its projection in the earlier frame, found
again in each view of the later one, triangulates to its new centroid; views that
disagree give no answer."""
import numpy as np
import pytest

from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import rotation_matrix, transform_points
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
