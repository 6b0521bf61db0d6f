"""Default anatomical frames from the implants' geometry, on the real meshes.

The biplane meshes are drawn in an anatomical frame (x mediolateral, y anterior, z
proximal: the reference poses give 21-73 deg flexion with it); the single-plane ones in
another (y along the stem, z mediolateral). The defaults must find those axes."""
from __future__ import annotations

import numpy as np
import pytest

from fluorogui.core.knee.anatomy import default_frame
from fluorogui.core.knee.kinematics import KinematicsError, check_frame
from fluorogui.io.meshes.read import load_mesh


def angle_deg(a, b):
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


@pytest.fixture(scope="module")
def meshes(shared_data):
    d = shared_data
    return {
        ("biplane", "femoral"): load_mesh(d / "biplane-tka" / "models" / "femoral_component.stl"),
        ("biplane", "tibial"): load_mesh(d / "biplane-tka" / "models" / "tibial_component.stl"),
        ("single", "femoral"): load_mesh(d / "single-plane-tka" / "KR_right_7_fem.stl"),
        ("single", "tibial"): load_mesh(d / "single-plane-tka" / "KR_right_6_tib.stl"),
    }


# expected model axes of anatomical x (right), y (anterior), z (proximal), and the limit (deg);
# measured: 0.97 (biplane femoral), 4.02 (single femoral), 0.060 (single tibial) at most
EXPECTED = {
    ("biplane", "femoral"): ([1, 0, 0], [0, 1, 0], [0, 0, 1], 1.0),
    ("biplane", "tibial"): ([1, 0, 0], [0, 1, 0], [0, 0, 1], 0.0015),  # measured 0.0007
    # its distal cut (the default's proximal axis) is tilted 3.8 deg against the file's y axis
    ("single", "femoral"): ([0, 0, -1], [-1, 0, 0], [0, 1, 0], 4.5),
    ("single", "tibial"): ([0, 0, -1], [-1, 0, 0], [0, 1, 0], 0.1),
}


@pytest.mark.parametrize("key", list(EXPECTED))
def test_default_axes_match_the_designs(meshes, key):
    vertices, faces = meshes[key]
    F = check_frame(default_frame(key[1], vertices, faces))
    *axes, limit = EXPECTED[key]
    for column, expected in enumerate(axes):
        assert angle_deg(F[:3, column], expected) < limit, (key, column, F[:3, :3].round(3))


def test_tibial_origin_is_the_centre_of_the_tray_top(meshes):
    vertices, faces = meshes[("biplane", "tibial")]
    F = default_frame("tibial", vertices, faces)
    assert F[:3, 3] == pytest.approx([0.0, 0.0, vertices[:, 2].max()], abs=0.05)  # measured 0.025 mm


def test_femoral_origin_is_the_condylar_centre(meshes):
    vertices, faces = meshes[("biplane", "femoral")]
    F = default_frame("femoral", vertices, faces)
    lowest = vertices[:, 2].min()
    radius = F[2, 3] - lowest
    assert 15.0 < radius < 35.0  # a condylar radius, above the distal surface
    assert abs(F[0, 3]) < 0.72  # midway between the condyles: measured -0.36 mm


@pytest.mark.parametrize("component", ["femoral", "tibial"])
def test_mirrored_implant_keeps_a_right_handed_frame(meshes, component):
    vertices, faces = meshes[("biplane", component)]
    mirror = np.diag([-1.0, 1.0, 1.0])
    F = check_frame(default_frame(component, vertices @ mirror, faces[:, ::-1]))
    Fo = default_frame(component, vertices, faces)
    assert angle_deg(F[:3, 1], mirror @ Fo[:3, 1]) < 1e-5  # anterior and proximal mirror: measured exactly
    assert angle_deg(F[:3, 2], mirror @ Fo[:3, 2]) < 1e-5
    assert np.linalg.det(F[:3, :3]) == pytest.approx(1.0)


def test_too_small_a_mesh_is_refused():
    with pytest.raises(KinematicsError, match="at least 4"):
        default_frame("tibial", np.zeros((3, 3)), np.array([[0, 1, 2]]))
    with pytest.raises(KinematicsError, match="patella"):
        default_frame("patella", np.zeros((4, 3)), np.zeros((4, 3), int))
