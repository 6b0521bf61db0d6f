"""find_components on the real biplane data (skips without ../shared/data): both
components from nothing in one frame, and tracking recovery near a perturbed pose."""

import numpy as np
import pytest

from fluorogui.core.projection.pose import angles_from_matrix, pose_error, rotation_matrix, rotvec_matrix
from fluorogui.core.search.find import find_components

pytestmark = pytest.mark.slow  # end to end on the real data


@pytest.fixture(scope="module")
def real(biplane):
    return biplane


def _errors(pose, truth):
    e = np.abs(pose_error(pose, truth))
    return e[:3].max(), e[3:].max()


def test_both_components_from_nothing(real):
    # frame 64: the tibial outline half fits many wrong orientations on blurred edges
    views, images, ref, meshes = real
    out = find_components(images("64"), views, meshes)
    for name, p in out.items():
        assert p.found, (name, p.reason)
        mm, deg = _errors(p.pose, ref[("64", name)])
        # against the reference poses (tests/data): measured femoral 0.0071 mm / 0.0059 deg,
        # tibial 0.025 mm / 0.079 deg
        assert mm < 0.05 and deg < 0.15, (name, mm, deg)
        # measured 0.119-0.137 mm, IoU 0.975-0.991
        assert max(p.per_view_mean_mm) < 0.2 and min(p.iou) > 0.96, (p.per_view_mean_mm, p.iou)


def test_recovery_near_a_perturbed_pose(real):
    views, images, ref, meshes = real
    rng = np.random.default_rng(11)
    near = {}
    for name, mesh in meshes.items():  # 8 mm and 20 degrees off
        pose = ref[("53", name)]
        R0 = rotation_matrix(*pose[3:])
        axis = rng.normal(size=3)
        R = rotvec_matrix(np.radians(20.0) * axis / np.linalg.norm(axis)) @ R0
        shift = rng.normal(size=3)
        c = R0 @ mesh.centroid + pose[:3] + 8.0 * shift / np.linalg.norm(shift)
        near[name] = np.r_[c - R @ mesh.centroid, angles_from_matrix(R)]
    out = find_components(images("53"), views, meshes, near=near)
    for name, p in out.items():
        assert p.found, (name, p.reason)
        mm, deg = _errors(p.pose, ref[("53", name)])
        assert mm < 0.022 and deg < 0.06, (name, mm, deg)  # measured 0.011 / 0.0055 mm, 0.017 / 0.032 deg


#: the tray's pose where tracking matched it (frames without a reference pose; issue 48)
TRACKED_TRAY = {"140": np.array([-25.248421, -57.999871, -172.788656, -154.746157, -171.81999, 73.314748]),
                "200": np.array([-127.288107, -33.207598, -130.232902, -154.812794, 174.669362, 64.18959]),
                "220": np.array([-162.883217, -42.574249, -118.879491, -157.823845, 172.510816, 64.310883])}


def test_the_tray_at_mid_flexion_is_found_beside_the_femur(real):
    # with the femoral component found first and masked, its masked pixels scored for free and
    # the tray's search went to positions beside it: frame 140 declined (1.5 px in view 2),
    # frame 200's best candidate 40 mm / 80 deg off. Then 200 and 220 were placed right but
    # declined, "best overlap 0.93 / 0.69 in view 1": the image outline closed its faint stem
    # by a chord across the gap (200: bulging beside it; 220: cutting across it), and the
    # region the chord enclosed counted as a misfit. Measured now: found, 0.00-0.02 mm /
    # 0.03-0.06 deg from tracking's pose, overlap 0.975-0.993
    views, images, _, meshes = real
    for frame, tracked in TRACKED_TRAY.items():
        p = find_components(images(frame), views, meshes)["tibial"]
        assert p.found, (frame, p.reason)
        mm, deg = _errors(p.pose, tracked)
        assert mm < 0.05 and deg < 0.1, (frame, mm, deg)
        assert min(p.iou) > 0.965, (frame, p.iou)
