"""Automatic initial pose on synthetic masks with a known answer."""
import time

import cv2
import numpy as np
import pytest

from fluorogui.core.geometry import View
from fluorogui.core.initialise import (
    SearchCancelled, assign_blobs, dark_blobs, field_of_view, orientation_grid, search_component, search_pose,
    silhouette_mask,
)
from fluorogui.core.mesh import prepare_mesh
from fluorogui.core.phantoms import femoral_component_mesh, tibial_component_mesh
from fluorogui.core.pose import pose_difference, rotation_matrix
from fluorogui.core.silhouette import mesh_silhouette

SIZE = (1024, 1024)
TRUTH = np.array([3.0, -5.0, 8.0, 25.0, -40.0, 15.0])


def _views():
    """Two views ~70 degrees apart, sources ~1000 mm from the origin (like the real data)."""
    a = np.radians(35.0)
    out = []
    for k, s in enumerate((-1, 1)):
        source = 1000.0 * np.array([s * np.sin(a), -np.cos(a), 0.0])
        out.append(View.looking_at(source, (0, 0, 0), (0, 0, 1), 1200.0, SIZE, 0.3, name=f"v{k + 1}"))
    return out


def _mask(mesh, pose, view):
    sil = mesh_silhouette(mesh, rotation_matrix(*pose[3:]), pose[:3], view)
    m = np.zeros(SIZE[::-1], np.uint8)
    cv2.fillPoly(m, [np.round(sil.points_px * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    return m > 0


@pytest.fixture(scope="module")
def femur():
    return prepare_mesh(*femoral_component_mesh())


def test_orientation_grid_is_spread_over_so3():
    R = orientation_grid(500)
    assert R.shape == (500, 3, 3)
    assert np.allclose(np.einsum("nij,nkj->nik", R, R), np.eye(3), atol=1e-9)
    # every random rotation is within ~25 degrees of a grid rotation
    rng = np.random.default_rng(1)
    from scipy.spatial.transform import Rotation
    probes = Rotation.random(50, random_state=rng).as_matrix()
    cos = (np.einsum("pij,nij->pn", probes, R) - 1) / 2
    nearest = np.degrees(np.arccos(np.clip(cos.max(1), -1, 1)))
    assert nearest.max() < 30.0


def test_silhouette_mask_matches_the_exact_silhouette(femur):
    view = _views()[0]
    R = rotation_matrix(*TRUTH[3:])
    exact = cv2.resize(_mask(femur, TRUTH, view).astype(np.uint8), (256, 256), interpolation=cv2.INTER_AREA) > 0
    fast = silhouette_mask(femur, R, TRUTH[:3], view, 0.25) > 0
    iou = (exact & fast).sum() / (exact | fast).sum()
    assert iou > 0.9


def test_search_pose_recovers_a_known_pose(femur):
    views = _views()
    masks = [_mask(femur, TRUTH, v) for v in views]
    t0 = time.perf_counter()
    calls = []
    res = search_component(femur, views, masks, n_orientations=500, progress=lambda k, n: calls.append((k, n)))
    seconds = time.perf_counter() - t0
    err = pose_difference(res.pose, TRUTH)
    assert np.all(np.abs(err[:3]) < 0.5) and np.all(np.abs(err[3:]) < 0.5), err
    assert min(res.iou) > 0.97 and res.objective_mm < 0.6  # mask staircase: ~0.5 px per view
    assert calls and calls[-1][0] == calls[-1][1]
    assert seconds < 20.0
    # the plain function returns just the pose
    assert search_pose is not None


def test_search_can_be_cancelled(femur):
    views = _views()
    masks = [_mask(femur, TRUTH, v) for v in views]
    with pytest.raises(SearchCancelled):
        search_pose(femur, views, masks, n_orientations=200, cancel=lambda: True)


def test_dark_blobs_finds_dark_components_inside_the_field_of_view():
    h, w = 512, 512
    yy, xx = np.mgrid[:h, :w]
    img = np.zeros((h, w), np.uint8)
    disc = (xx - 255.5) ** 2 + (yy - 255.5) ** 2 < 240 ** 2
    img[disc] = 200
    img[disc & (xx > 330)] = 120  # soft tissue, gradual
    img = cv2.GaussianBlur(img, (0, 0), 4)
    cv2.ellipse(img, (200, 180), (60, 40), 0, 0, 360, 40, -1)  # "femoral"
    cv2.rectangle(img, (150, 300), (260, 340), 45, -1)  # "tibial"
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    fov = field_of_view(img, margin_px=10)
    assert not fov[0, 0] and fov[256, 256]
    blobs = dark_blobs(img, min_area=500, margin_px=10)
    assert len(blobs) >= 2
    cents = sorted([tuple(np.round(b.centroid)) for b in blobs[:2]])
    assert np.allclose(cents[0], (200, 180), atol=3) and np.allclose(cents[1], (205, 320), atol=3)
    mask, area, centroid = blobs[0]  # a blob unpacks as (mask, area, centroid)
    assert mask.dtype == bool and area == mask.sum()


def test_assign_blobs_pairs_the_right_blobs():
    views = _views()
    fem = prepare_mesh(*femoral_component_mesh())
    tib = prepare_mesh(*tibial_component_mesh())
    fem_pose = np.array([0.0, 0.0, 30.0, 10.0, 20.0, 5.0])
    tib_pose = np.array([0.0, 0.0, -40.0, 5.0, -10.0, 0.0])
    from fluorogui.core.initialise import Blob

    def blob(mask):
        v, u = np.nonzero(mask)
        return Blob(mask, int(mask.sum()), np.array([u.mean(), v.mean()]))

    blobs = [[blob(_mask(tib, tib_pose, v)), blob(_mask(fem, fem_pose, v))] for v in views]
    out = assign_blobs({"femoral": fem, "tibial": tib}, views, blobs, n_orientations=150, keep=2, refine=1)
    assert out["femoral"].blob_indices == (1, 1) and out["tibial"].blob_indices == (0, 0)
    assert min(out["femoral"].result.iou) > 0.9


def test_field_of_view_with_a_frame_that_is_not_black():
    # the frame of some intensifier images (and of the generated sequences) is dark grey
    # and noisy, darker than the field but not than a quarter of the metal's grey
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:512, 0:512]
    disc = (xx - 256) ** 2 + (yy - 256) ** 2 < 230 ** 2
    img = np.where(disc, 200.0, 16.0) + rng.normal(0, 5, (512, 512))
    cv2.ellipse(img, (256, 256), (40, 30), 0, 0, 360, 50, -1)  # metal, darker than the frame's quarter
    fov = field_of_view(np.clip(img, 0, 255).astype(np.uint8), margin_px=10)
    assert fov[256, 256] and not fov[5, 5] and not fov[256, 20]
    assert abs(fov.sum() - np.pi * 220 ** 2) < 0.03 * np.pi * 220 ** 2
