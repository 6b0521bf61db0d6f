import numpy as np
import pytest

from fluorogui.core.outlines.spline import resample_closed_polyline
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import MeshError, prepare_mesh, sample_surface
from fluorogui.core.projection.point_outline import grid_outline
from fluorogui.core.projection.pose import rotation_matrix
from fluorogui.core.projection.silhouette import mesh_silhouette
from fluorogui.simulation.phantoms import femoral_component_mesh, sphere_mesh


def _view():
    return View.looking_at([0, -1000, 0], [0, 0, 0], [0, 0, 1], 1200.0, image_size=(1024, 1024), pitch=0.3)


def test_sphere_silhouette_is_the_exact_circle():
    v, f = sphere_mesh(40.0, subdivisions=5)
    mesh = prepare_mesh(v, f)
    view = _view()
    sil = mesh_silhouette(mesh, np.eye(3), np.zeros(3), view)
    centre = view.project(np.zeros((1, 3)))[0]
    # a sphere of radius r at distance D projects to a circle of radius f*r/sqrt(D^2 - r^2)
    expected = view.focal_px[0] * 20.0 / np.sqrt(1000.0**2 - 20.0**2)
    radii = np.linalg.norm(sil.points_px - centre, axis=1)
    # the polyhedral sphere is inscribed: within the facet sagitta of the true circle
    assert radii.max() <= expected + 1e-6
    assert expected - radii.mean() < 0.00036 * expected  # measured 0.00018
    # the outline is ordered: consecutive points are close
    gaps = np.linalg.norm(np.diff(sil.points_px, axis=0), axis=1)
    assert gaps.max() < 1.43  # measured 0.71 px


def test_silhouette_points_carry_their_model_points():
    v, f = femoral_component_mesh()
    mesh = prepare_mesh(v, f)
    R, t = rotation_matrix(20, -30, 10), np.array([3.0, -4.0, 5.0])
    view = _view()
    sil = mesh_silhouette(mesh, R, t, view)
    assert np.allclose(view.project(sil.model_points @ R.T + t), sil.points_px, atol=1e-8)
    sub = sil.resample(n=60)
    assert len(sub.points_px) == 60


def _filled_outline(mesh, R, t, view, cells_per_px: int = 16) -> np.ndarray:
    """An outline made without the silhouette code: the outer contour of every projected
    triangle filled at ``cells_per_px`` (its cell centres, so within ~1/32 px of the edge)."""
    import cv2

    uv = view.project(mesh.vertices @ R.T + t)
    origin = uv.min(0) - 2
    size = np.ceil((uv.max(0) - origin + 2) * cells_per_px).astype(int)
    canvas = np.zeros((size[1], size[0]), np.uint8)
    cv2.fillPoly(canvas, list(np.round((uv[mesh.faces] - origin) * cells_per_px * 16).astype(np.int32)), 1,
                 cv2.LINE_8, 4)
    contours, _ = cv2.findContours(canvas, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    return (max(contours, key=len)[:, 0, :] + 0.5) / cells_per_px + origin


def _distance_to_polyline(points, polyline):
    from scipy.spatial import cKDTree

    nearest = cKDTree(polyline).query(points, k=4)[1]
    best = np.full(len(points), np.inf)
    for a, b in ((polyline, np.roll(polyline, -1, 0)), (np.roll(polyline, 1, 0), polyline)):
        for j in range(4):
            p0, d = a[nearest[:, j]], b[nearest[:, j]] - a[nearest[:, j]]
            lam = np.clip(np.sum((points - p0) * d, 1) / np.maximum(np.sum(d * d, 1), 1e-12), 0, 1)
            best = np.minimum(best, np.linalg.norm(p0 + lam[:, None] * d - points, axis=1))
    return best


def test_silhouette_lies_on_the_outline_of_the_filled_triangles():
    mesh = prepare_mesh(*femoral_component_mesh())
    view = _view()
    rng = np.random.default_rng(0)
    distances = []
    for _ in range(4):
        pose = np.r_[rng.normal(0, 5, 3), rng.uniform(-40, 40, 3)]
        R = rotation_matrix(*pose[3:])
        reference = _filled_outline(mesh, R, pose[:3], view)
        for spacing in (None, 2.0):
            outline = mesh_silhouette(mesh, R, pose[:3], view, spacing_px=spacing).points_px
            distances.append(_distance_to_polyline(outline, reference))
    d = np.concatenate(distances)
    # measured mean 0.029 px (mostly the reference's own cells), 99 % within 0.078 px,
    # largest 0.28 px (where an inner silhouette edge meets the outer one)
    assert d.mean() < 0.058 and np.percentile(d, 99) < 0.156 and d.max() < 0.56, (d.mean(), d.max())


def test_grid_outline_of_a_disc_lies_just_inside_it():
    rng = np.random.default_rng(0)
    th, r = rng.uniform(0, 2 * np.pi, 20000), 100 * np.sqrt(rng.uniform(0, 1, 20000))
    pts = np.column_stack([r * np.cos(th), r * np.sin(th)]) + 300
    outline = grid_outline(pts, 3.0)
    radii = np.linalg.norm(outline - 300, axis=1)
    assert radii.max() <= 100.0 and radii.mean() > 99.0  # measured 99.998, 99.51
    # ordered around the disc: angles change monotonically (one way) apart from the wrap
    ang = np.unwrap(np.arctan2(outline[:, 1] - 300, outline[:, 0] - 300))
    assert abs(ang[-1] - ang[0]) > 1.9 * np.pi
    spaced = resample_closed_polyline(outline, n=60)
    steps = np.linalg.norm(np.diff(spaced, axis=0), axis=1)
    assert len(spaced) == 60 and steps.std() < 0.044 * steps.mean()  # measured 0.022


def test_surface_sampling_is_even_and_exact_in_count():
    v, f = sphere_mesh(50.0, subdivisions=4)
    pts = sample_surface(v, f, 3500)
    assert pts.shape == (3500, 3)
    assert np.allclose(np.linalg.norm(pts, axis=1), 25.0, atol=0.057)  # on the facets: measured 0.028 mm inside
    from scipy.spatial import cKDTree

    d, _ = cKDTree(pts).query(pts, k=2)
    # blue noise: no clumps (random sampling gives many near-zero neighbour distances)
    assert np.percentile(d[:, 1], 1) > 0.3 * np.median(d[:, 1])


def test_meshes_without_faces_or_with_nan_are_refused():
    with pytest.raises(MeshError, match="no faces"):
        prepare_mesh(np.zeros((3, 3)), np.zeros((0, 3), int))
    with pytest.raises(MeshError, match="NaN"):
        prepare_mesh(np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), np.array([[0, 1, 2]]))
