"""The region-overlap reference fitter (``fluorogui.reference.region_fit``): its own pose
convention and rasteriser against hand computations and the X-ray model's independent
ray casting, its accuracy on X-ray model image pairs with a known pose (a tray on a plain
background and on the sloped one of bone and cement), the fits it refuses, the other
component's mask, and one real frame (skips without ../shared/data)."""
import csv
from pathlib import Path

import numpy as np
import pytest

from fluorogui.core.projection.geometry import View
from fluorogui.reference.region_fit import (
    EdgeMesh,
    LowOverlap,
    angles,
    component_masks,
    coverage,
    field_of_view,
    fit_pose,
    pose_difference,
    project,
    rotation,
    rotation_angle,
)
from fluorogui.reference.xray import MU_TISSUE, Body, Cylinder, XrayModel, path_length, xray_image
from fluorogui.reference.zone import REAL_BLUR_PX, tray_zone

REFERENCE_POSES = Path(__file__).resolve().parents[1] / "data" / "biplane_reference_poses.csv"
VIEW = View.looking_at([-1000.0, 0, 0], [0, 0, 0], [0, 0, 1], 1200.0, image_size=(128, 128), pitch=0.5)


def _mesh(polydata):
    tri = polydata.triangulate()
    return np.asarray(tri.points, dtype=float), np.asarray(tri.faces).reshape(-1, 4)[:, 1:]


def test_rotation_is_the_design_convention_and_angles_come_back():
    a, b, g = np.radians([20.0, -35.0, 50.0])
    Rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    Ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    Rz = np.array([[np.cos(g), -np.sin(g), 0], [np.sin(g), np.cos(g), 0], [0, 0, 1]])
    R = rotation(20.0, -35.0, 50.0)
    np.testing.assert_allclose(R, Ry @ Rz @ Rx, atol=1e-12)
    # docs/developer/conventions.rst: the corrected element (3,1) of the paper's Eq. (2), transposed: R[0, 2]
    assert R[0, 2] == pytest.approx(np.sin(a) * np.cos(b) * np.sin(g) + np.cos(a) * np.sin(b))
    np.testing.assert_allclose(angles(R), [20.0, -35.0, 50.0], atol=1e-10)
    np.testing.assert_allclose(pose_difference([0, 0, 0, 179, -179, 10], [0, 0, 0, -179, 179, 350]),
                               [0, 0, 0, -2, 2, 20], atol=1e-12)
    # near gamma = 90 deg a 1 deg turn shows as much larger, opposite alpha and beta changes
    turned = np.r_[0, 0, 0, angles(rotation(10.0, 20.0, 88.0) @ rotation(0.0, 1.0, 0.0).T @ rotation(0.0, 0.0, 0.0))]
    assert rotation_angle(turned, [0, 0, 0, 10.0, 20.0, 88.0]) == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(project(VIEW, [[0.0, 0.0, 0.0]]), [VIEW.principal_point], atol=1e-9)


def test_coverage_is_the_x_ray_models_shadow_of_a_closed_mesh():
    import pyvista as pv

    # a concave closed mesh (two front layers overlap in projection) and a sphere
    torus = pv.ParametricTorus(ringradius=12.0, crosssectionradius=4.0).rotate_y(60.0).translate((0, 3, -2))
    for poly in (torus, pv.Sphere(radius=10.0, center=(20.0, 3.0, -2.0), theta_resolution=90, phi_resolution=90)):
        v, f = _mesh(poly)
        cover = coverage(VIEW, v, EdgeMesh.from_arrays(v, f), (0, 0, 128, 128), s=4)
        # independent: ray casting of the X-ray model, 4 x 4 rays per pixel
        shadow = (path_length(VIEW, Body(v, f), 4, (0, 0, 128, 128)) > 1e-9).reshape(128, 4, 128, 4).mean((1, 3))
        assert cover.max() == pytest.approx(1.0) and cover.min() == 0.0
        # measured: total area within 0.021 / 0.035 px2 (torus / sphere), no pixel off by more
        # than one edge sample row (0.110 / 0.094)
        assert abs(cover.sum() - shadow.sum()) < 0.07, (cover.sum(), shadow.sum())
        assert np.abs(cover - shadow).max() < 0.22


def test_field_of_view_is_the_lit_disc_with_its_dark_metal():
    yy, xx = np.mgrid[:200, :200]
    image = np.where((xx - 100) ** 2 + (yy - 100) ** 2 < 90 ** 2, 0.6, 0.0).astype(np.float32)
    image[40:60, 20:160] = 0.0  # black metal reaching across the disc
    r2 = (xx - 100) ** 2 + (yy - 100) ** 2
    fov = field_of_view(image, erode_px=0)  # the smoothing before the threshold widens it ~5 px
    assert fov[r2 < 89 ** 2].all() and not fov[r2 > 96 ** 2].any()
    assert not field_of_view(image)[r2 > 90 ** 2].any()  # the default erosion takes it back


@pytest.fixture(scope="module")
def tray_scene():
    from fluorogui.simulation.phantoms import tibial_component_mesh
    from fluorogui.simulation.protocols import flexion_pose, two_views

    mesh = tibial_component_mesh()
    v, f = np.asarray(mesh[0], dtype=float), np.asarray(mesh[1])
    views = two_views(70.0, 10.0, image_size=(384, 384), pitch=0.8)
    truth = flexion_pose(v, 45.0)
    world = v @ rotation(*truth[3:]).T + truth[:3]
    model = XrayModel(supersample=2)
    images = [xray_image(view, [Body(world, f)], model, np.random.default_rng(k)) for k, view in enumerate(views)]
    return views, images, EdgeMesh.from_arrays(v, f), truth


@pytest.mark.slow
def test_fit_on_x_ray_model_images_recovers_the_pose(tray_scene):
    views, images, mesh, truth = tray_scene
    start = truth + np.array([1.5, -1.5, 1.0, -1.5, 1.5, 1.0])
    fit = fit_pose(views, images, mesh, start)
    err = pose_difference(fit.pose, truth)
    # measured over 6 starts (384 px of 0.8 mm, ~0.65 mm at the object): x -0.13..-0.21 mm,
    # y and z <= 0.08 mm, angles <= 0.46 deg; the same sign of x from every start (the thin
    # tray's rim is lighter than the metal level: the region looks smaller)
    assert -0.3 < err[0] < -0.06 and np.abs(err[1:3]).max() < 0.16, err
    assert np.abs(err[3:]).max() < 0.7, err
    assert min(fit.iou) > 0.92 and fit.success
    assert fit.iou_at(mesh, fit.pose) == pytest.approx(fit.iou)  # the same evidence
    # the start overlaps worse in each view (measured 0.83-0.87 / 0.78-0.87 against 0.98 / 0.96)
    assert all(a < b - 0.03 for a, b in zip(fit.iou_at(mesh, start), fit.iou))


@pytest.fixture(scope="module")
def sloped_tray_scene():
    """The phantom tray seen edge-on as on the real frames (0.31 mm pixels), on the real
    images' background: soft tissue along it, bone and cement under its plate and around
    its keel (``tray_zone``), the real edges' blur."""
    from fluorogui.core.projection.pose import pose_to_matrix
    from fluorogui.simulation.phantoms import tibial_component_mesh
    from fluorogui.simulation.protocols import flexion_pose, two_views

    v, f = (np.asarray(a) for a in tibial_component_mesh())
    views = two_views(70.0, 10.0, image_size=(448, 448), pitch=315.0 / 1024.0)
    truth = flexion_pose(v, 5.0)
    M = pose_to_matrix(truth)
    world = v @ M[:3, :3].T + M[:3, 3]
    model = XrayModel(supersample=2, detector_blur_px=REAL_BLUR_PX, zones=[tray_zone(v, f, M)],
                      background=[Cylinder(tuple(world.mean(0)), tuple(M[:3, 2]), 50.0, MU_TISSUE)])
    images = [xray_image(view, [Body(world, f)], model, np.random.default_rng(k)) for k, view in enumerate(views)]
    return views, images, EdgeMesh.from_arrays(v, f), truth


@pytest.mark.slow
def test_fit_on_a_sloped_background_reads_the_background_at_the_edge(sloped_tray_scene):
    from fluorogui.core.projection.pose import body_difference

    views, images, mesh, truth = sloped_tray_scene
    centroid = mesh.vertices.mean(0)
    start = truth + np.array([0.4, -0.4, 0.3, -0.4, 0.4, 0.3])
    fit = fit_pose(views, images, mesh, start)
    err = body_difference(fit.pose, truth, centroid)
    # measured from three starts: centroid within 0.066 mm (along the stem, world z,
    # -0.037..-0.044), turns within 0.25 deg
    assert np.abs(err[:3]).max() < 0.13 and -0.09 < err[2] < 0.09 and np.abs(err[3:]).max() < 0.5, err
    # the background read 6-18 px out (as before this reading) lies on the bone's slope:
    # the metal region swells into the bone under the plate and around the keel, and the
    # fit sinks along the stem (measured -0.172 mm)
    wide = (3.0, 1, 0.4, ("ring", 6.0, 18.0)), (1.0, 3, 0.2, ("ring", 6.0, 18.0))
    before = body_difference(fit_pose(views, images, mesh, start, stages=wide, settle=0).pose, truth, centroid)
    assert before[2] < -0.12, before


def test_a_fit_that_found_too_little_is_refused(tray_scene):
    views, images, mesh, truth = tray_scene
    far = truth + np.array([0.0, 0.0, 60.0, 0.0, 0.0, 0.0])  # its window holds none of the tray
    with pytest.raises(LowOverlap, match="overlap in view") as refused:
        fit_pose(views, images, mesh, far, max_nfev=3)
    assert min(refused.value.fit.iou) < 0.5
    assert fit_pose(views, images, mesh, far, max_nfev=3, min_iou=None).iou == refused.value.fit.iou


def test_the_other_components_mask_is_its_region_dilated():
    import cv2
    import pyvista as pv

    v, f = _mesh(pv.Sphere(radius=10.0, theta_resolution=60, phi_resolution=60))
    mesh = EdgeMesh.from_arrays(v, f)
    (mask,) = component_masks([VIEW], mesh, [5.0, 0.0, 0.0, 0.0, 0.0, 0.0], dilate_px=3)
    region = coverage(VIEW, v + [5.0, 0.0, 0.0], mesh, (0, 0, 128, 128), s=1) > 1e-3
    assert mask.shape == (128, 128) and mask[region].all()
    away = cv2.distanceTransform((~region).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    # a disc of radius 3 px reaches (1, 3) px off: sqrt(10)
    assert away[mask].max() <= np.sqrt(10.0) + 1e-4 and mask[(away > 0) & (away <= 2.0)].all()


@pytest.mark.slow
def test_one_real_frame_from_a_moved_start(shared_data):
    from fluorogui.io.calibration import load_view
    from fluorogui.io.images import read_image
    from fluorogui.io.meshes.read import load_mesh

    d = shared_data / "biplane-tka"
    views = [load_view(d / "calibration" / f"cam{k}_mayacam2.txt") for k in (1, 2)]
    images = [read_image(d / "cam1/000000.tif"), read_image(d / "cam2/000522.tif")]
    mesh = EdgeMesh.from_arrays(*load_mesh(d / "models/femoral_component.stl"))
    with open(REFERENCE_POSES, newline="") as fh:  # not relative to the working directory
        row = next(r for r in csv.DictReader(fh) if r["frame"] == "0" and r["component"] == "femoral")
    matcher = np.array([float(row[k]) for k in ("x", "y", "z", "alpha", "beta", "gamma")])
    fields = [field_of_view(im) for im in images]
    fit = fit_pose(views, images, mesh, matcher + np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0]), fields=fields)
    diff = pose_difference(matcher, fit.pose)
    # measured: 0.044 mm and a 0.074 deg turn from the matcher's pose (the fit from the
    # matcher's pose itself: 0.013 mm, 0.03 deg), IoU 0.986 / 0.988
    assert np.abs(diff[:3]).max() < 0.087, diff
    assert rotation_angle(matcher, fit.pose) < 0.147, diff
    assert min(fit.iou) > 0.98


def test_the_fitter_imports_nothing_of_fluorogui():
    """The import-linter contract on ``fluorogui.validation`` covers it; this names it."""
    import ast
    import inspect

    from fluorogui.reference import region_fit

    tree = ast.parse(inspect.getsource(region_fit))
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert names and not [n for n in names if n.startswith("fluorogui")]


def test_overlap_at_a_given_pose_tells_a_right_pose_from_a_wrong_one(tray_scene):
    from fluorogui.reference.region_fit import overlap_at

    views, images, mesh, truth = tray_scene
    right = overlap_at(views, images, mesh, truth)
    # a pose 16 mm off along view 1's beam: it still covers the tray in view 1, not in view 2
    beam = np.asarray(views[0].normal, float)
    moved = truth.copy()
    moved[:3] += 16.0 * beam
    wrong = overlap_at(views, images, mesh, moved)
    # measured: the truth 0.979 / 0.962; 4, 8, 12 mm along view 1's beam: view 1 0.97-0.98,
    # view 2 0.77, 0.63, 0.48
    assert min(right) > 0.95, right
    assert wrong[0] > 0.95 and wrong[1] < 0.45, wrong
    fit = fit_pose(views, images, mesh, truth)
    assert overlap_at(views, images, mesh, fit.pose) == pytest.approx(fit.iou, abs=0.02)
