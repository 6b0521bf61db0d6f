import numpy as np
import pytest

from fluorogui.core.projection.pose import (
    angles_from_matrix,
    as_pose,
    matrix_to_pose,
    paper_eq2_matrix,
    pose_difference,
    pose_to_matrix,
    rotation_matrix,
    transform_points,
)


def _rx(a):
    a = np.radians(a)
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def _ry(b):
    b = np.radians(b)
    return np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])


def _rz(g):
    g = np.radians(g)
    return np.array([[np.cos(g), -np.sin(g), 0], [np.sin(g), np.cos(g), 0], [0, 0, 1]])


@pytest.mark.parametrize("angles", [(10, 20, 30), (-75, 140, 60), (0, 0, 0), (5, -170, -80)])
def test_rotation_is_ry_rz_rx_and_transpose_of_corrected_eq2(angles):
    R = rotation_matrix(*angles)
    assert np.allclose(R, _ry(angles[1]) @ _rz(angles[2]) @ _rx(angles[0]))
    assert np.allclose(R.T, paper_eq2_matrix(*angles))
    assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)


def test_misprinted_element_is_corrected():
    a, b, g = np.radians([30.0, 40.0, 50.0])
    printed = np.sin(a) * np.cos(b) * np.sin(g) + np.cos(a) * np.cos(b)  # the misprint
    fixed = np.sin(a) * np.cos(b) * np.sin(g) + np.cos(a) * np.sin(b)
    assert np.isclose(paper_eq2_matrix(30, 40, 50)[2, 0], fixed)
    assert not np.isclose(paper_eq2_matrix(30, 40, 50)[2, 0], printed)


def test_angles_round_trip_in_the_principal_range():
    rng = np.random.default_rng(3)
    for _ in range(200):
        a, b = rng.uniform(-179, 179, 2)
        g = rng.uniform(-89, 89)
        assert np.allclose(angles_from_matrix(rotation_matrix(a, b, g)), (a, b, g), atol=1e-9)


def test_pose_matrix_round_trip_and_transform():
    pose = np.array([1.5, -2.0, 300.0, 12.0, -33.0, 45.0])
    assert np.allclose(matrix_to_pose(pose_to_matrix(pose)), pose)
    m = np.array([[1.0, 2.0, 3.0]])
    expected = rotation_matrix(*pose[3:]) @ m[0] + pose[:3]
    assert np.allclose(transform_points(pose, m)[0], expected)


def test_as_pose_rejects_nan_and_wrong_length():
    with pytest.raises(ValueError, match="NaN"):
        as_pose([0, 0, 0, np.nan, 0, 0])
    with pytest.raises(ValueError, match="6 numbers"):
        as_pose([0, 0, 0])


def test_pose_difference_wraps_angles():
    d = pose_difference([0, 0, 0, 179, -179, 0], [0, 0, 0, -179, 179, 0])
    assert np.allclose(d[3:], [-2, 2, 0])


def test_pose_error_is_the_body_fixed_rotation_even_at_gimbal_lock():
    from fluorogui.core.projection.pose import pose_error, rotvec_matrix

    truth = np.array([1.0, 2.0, 3.0, 20.0, 30.0, 89.9])
    R = rotation_matrix(*truth[3:]) @ rotvec_matrix(np.radians([0.0, 0.01, 0.0]))
    est = np.r_[truth[:3] + [0.1, 0.0, 0.0], angles_from_matrix(R)]
    err = pose_error(est, truth)
    assert np.allclose(err, [0.1, 0, 0, 0, 0.01, 0], atol=1e-6)
    # plain Euler differences blow up near gamma = 90 deg
    assert np.abs(pose_difference(est, truth)[3:]).max() > 0.05


def test_body_difference_is_the_centroid_shift_and_the_turn_about_the_model_axes():
    from fluorogui.core.projection.pose import body_difference, rotvec_matrix

    reference = np.array([1.0, 2.0, 3.0, 20.0, 30.0, 40.0])
    centroid = np.array([10.0, 0.0, 0.0])
    R0 = rotation_matrix(*reference[3:])
    R1 = R0 @ rotvec_matrix(np.radians([0.0, 0.0, 2.0]))  # 2 deg about the model's own z
    # keep the centroid where it was, then move it 0.5 mm along world x
    t = R0 @ centroid + reference[:3] - R1 @ centroid + [0.5, 0.0, 0.0]
    pose = np.r_[t, angles_from_matrix(R1)]
    np.testing.assert_allclose(body_difference(pose, reference, centroid), [0.5, 0, 0, 0, 0, 2.0], atol=1e-9)
    np.testing.assert_allclose(body_difference(reference, reference, centroid), np.zeros(6), atol=1e-12)
