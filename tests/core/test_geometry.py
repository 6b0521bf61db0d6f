import numpy as np
import pytest

from fluorogui.core.projection.geometry import GeometryError, View, closest_point_between_rays, triangulate


def _view():
    return View.looking_at([0, -1000, 0], [0, 0, 0], [0, 0, 1], 1200.0, image_size=(1024, 1024), pitch=0.3)


def test_projection_is_eq3_on_the_plane_and_pixels_agree():
    v = _view()
    X = np.array([[10.0, 5.0, 20.0], [-30.0, 40.0, -5.0]])
    on_plane = v.project_plane(X)
    # Eq. (3): the projected point lies on the plane at distance l along the normal
    assert np.allclose((on_plane - v.source) @ v.normal, v.distance)
    assert np.allclose(v.pixel_to_plane(v.project(X)), on_plane)
    # image centre sees the principal ray; z up means rows decrease
    assert np.allclose(v.project(np.array([[0.0, 0.0, 0.0]])), [[511.5, 511.5]])
    assert v.project(np.array([[0.0, 0.0, 10.0]]))[0, 1] < 511.5


def test_pinhole_round_trip_matches_opencv_projection():
    K = np.array([[4576.8, 0, 395.3], [0, 4601.7, 588.4], [0, 0, 1]])
    a = np.radians(35)
    R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    t = np.array([36.0, -134.0, 1345.0])
    v = View.from_pinhole(K, R, t, (1024, 1024))
    X = np.random.default_rng(0).normal(0, 40, (20, 3))
    xc = X @ R.T + t
    uv = (xc @ K.T)[:, :2] / xc[:, 2:]
    assert np.allclose(v.project(X), uv, atol=1e-9)
    assert np.allclose(v.K, K) and np.allclose(v.R, R, atol=1e-12) and np.allclose(v.t, t)
    assert np.allclose(View.from_dict(v.to_dict()).project(X), uv)


def test_jacobian_matches_finite_differences():
    v = _view()
    X = np.array([[12.0, -7.0, 33.0]])
    _, J = v.project_jacobian(X)
    h = 1e-5
    num = np.column_stack([(v.project(X + h * e) - v.project(X - h * e))[0] / (2 * h) for e in np.eye(3)])
    assert np.allclose(J[0], num, atol=1e-6)


def test_rays_triangulate_a_point_and_report_the_miss():
    v1, v2 = _view(), View.looking_at([-1000, 0, 0], [0, 0, 0], [0, 0, 1], 1200.0, image_size=(1024, 1024), pitch=0.3)
    X = np.array([[10.0, 5.0, 20.0]])
    p, miss = triangulate([v1, v2], [v1.project(X)[0], v2.project(X)[0]])
    assert np.allclose(p, X[0], atol=1e-9) and miss < 1e-9
    point, miss = closest_point_between_rays([0, 0, 0], [1, 0, 0], [0, 1, 2], [0, 0, 1])
    assert np.isclose(miss, 1.0) and np.allclose(point, [0, 0.5, 0])


@pytest.mark.parametrize("K,R,message", [
    (np.array([[np.nan, 0, 1], [0, 1, 1], [0, 0, 1]]), np.eye(3), "NaN"),
    (np.zeros((3, 3)), np.eye(3), "singular"),
    (np.eye(3) * 1000, np.diag([1.0, 1.0, 2.0]), "rotation"),
])
def test_bad_pinhole_calibrations_are_refused(K, R, message):
    with pytest.raises(GeometryError, match=message):
        View.from_pinhole(K, R, np.zeros(3), (1024, 1024))
