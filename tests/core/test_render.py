"""Silhouette coverage and pseudo-fluoroscopic images (fluorogui.simulation.render). The
large mesh's render time: benchmarks/bench_budgets.py."""
import numpy as np
from scipy.spatial import ConvexHull

from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.pose import transform_points
from fluorogui.simulation.render import render_fluoro, render_silhouette


def overhead_view(size=128, pitch=0.25):
    """Source 1000 mm above the z = 0 plane, intensifier at 1000 mm: plane z=0 at 1:1."""
    return View.looking_at([0, 0, -1000], [0, 0, 0], [0, -1, 0], 1000.0, image_size=(size, size), pitch=pitch)


def cube(edge):
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float) - 0.5
    faces = []
    for axis in range(3):
        for side in (0, 1):
            quad = [i for i, c in enumerate(corners) if (c[axis] > 0) == bool(side)]
            a, b, c, d = sorted(quad, key=lambda i: np.arctan2(*np.delete(corners[i], axis)[::-1]))
            faces += [[a, b, c], [a, c, d]]
    return corners * edge, np.array(faces)


def square_in_plane(u0, v0, u1, v1, view):
    """Mesh (two triangles) of the plane z=0 square whose projection spans pixels u0..u1, v0..v1."""
    corners = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]], dtype=float)
    world = view.pixel_to_plane(corners)
    world = view.source + (world - view.source) * (1000.0 / view.distance)
    return world, np.array([[0, 1, 2], [0, 2, 3]])


def test_pixel_centre_convention_square_on_pixel_edges():
    view = overhead_view()
    vertices, faces = square_in_plane(9.5, 19.5, 29.5, 24.5, view)
    cov = render_silhouette(view, vertices, faces)
    expected = np.zeros_like(cov)
    expected[20:25, 10:30] = 1.0
    np.testing.assert_allclose(cov, expected, atol=1e-12)


def test_partial_pixels_get_fractional_coverage():
    view = overhead_view()
    vertices, faces = square_in_plane(10.0, 20.0, 30.0, 25.0, view)  # edges through pixel centres
    cov = render_silhouette(view, vertices, faces, supersample=8)
    assert cov[22, 10] == 0.5 and cov[22, 30] == 0.5 and cov[22, 20] == 1.0
    assert abs(cov.sum() - 20 * 5) < 1e-9


def test_cube_coverage_equals_projected_area():
    view = overhead_view(size=256)
    vertices, faces = cube(20.0)
    world = transform_points([1.3, -2.2, 40.0, 25.0, 37.0, -12.0], vertices)
    cov = render_silhouette(view, world, faces, supersample=8)
    area = ConvexHull(view.project(world)).volume  # a convex body projects to its vertices' hull
    assert abs(cov.sum() - area) / area < 1.3e-5  # measured 6.4e-6


def test_overlapping_triangles_are_a_union_not_xor():
    view = overhead_view()
    vertices, faces = square_in_plane(10.0, 10.0, 60.0, 60.0, view)
    single = render_silhouette(view, vertices, faces)
    # the same square drawn by overlapping triangles: both diagonals and a duplicate
    overlapping = np.array([[0, 1, 2], [0, 2, 3], [1, 2, 3], [0, 1, 3], [0, 1, 2]])
    cov = render_silhouette(view, vertices, overlapping)
    np.testing.assert_allclose(cov, single, atol=1e-12)
    assert cov.max() <= 1.0


def uv_sphere(radius, n_lat, n_lon):
    lat = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    lon = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    ring = np.stack(np.meshgrid(lat, lon, indexing="ij"), -1).reshape(-1, 2)
    pts = np.column_stack([np.sin(ring[:, 0]) * np.cos(ring[:, 1]), np.sin(ring[:, 0]) * np.sin(ring[:, 1]),
                           np.cos(ring[:, 0])])
    vertices = np.vstack([pts, [[0, 0, 1], [0, 0, -1]]]) * radius
    top, bottom = len(pts), len(pts) + 1
    faces = []
    idx = np.arange(len(pts)).reshape(n_lat - 1, n_lon)
    nxt = np.roll(idx, -1, axis=1)
    faces.append(np.column_stack([idx[:-1].ravel(), idx[1:].ravel(), nxt[1:].ravel()]))
    faces.append(np.column_stack([idx[:-1].ravel(), nxt[1:].ravel(), nxt[:-1].ravel()]))
    faces.append(np.column_stack([np.full(n_lon, top), idx[0], nxt[0]]))
    faces.append(np.column_stack([np.full(n_lon, bottom), nxt[-1], idx[-1]]))
    return vertices, np.vstack(faces)


def test_large_mesh_matches_disc_area():
    view = overhead_view(size=1024, pitch=0.25)
    vertices, faces = uv_sphere(30.0, 121, 304)  # ~73k triangles
    assert len(faces) > 70000
    cov = render_silhouette(view, vertices + [0, 0, 50.0], faces)
    # the sphere's silhouette from a point source is a circle of radius d r / sqrt(D^2 - r^2)
    D = 1050.0
    radius_px = 1000.0 * 30.0 / np.sqrt(D**2 - 30.0**2) / 0.25
    assert abs(cov.sum() - np.pi * radius_px**2) / (np.pi * radius_px**2) < 3.3e-4  # polygonal sphere: 1.6e-4


def test_render_fluoro_dark_component_on_bright_background():
    view = overhead_view(size=128)
    vertices, faces = square_in_plane(40.0, 40.0, 90.0, 90.0, view)
    image = render_fluoro(view, [(vertices, faces)], np.random.default_rng(3))
    assert image.dtype == np.float32 and image.shape == (128, 128)
    assert 0.0 <= image.min() and image.max() <= 1.0
    inside, outside = image[55:75, 55:75].mean(), image[5:25, 5:25].mean()
    assert outside - inside > 0.4
    again = render_fluoro(view, [(vertices, faces)], np.random.default_rng(3))
    np.testing.assert_array_equal(image, again)


def test_render_fluoro_components_union():
    view = overhead_view(size=128)
    a = square_in_plane(20.0, 20.0, 70.0, 70.0, view)
    b = square_in_plane(40.0, 40.0, 100.0, 100.0, view)
    kwargs = dict(noise_sd=0.0, blur_sigma_px=0.0, background="flat")
    image = render_fluoro(view, [a, b], np.random.default_rng(0), **kwargs)
    assert abs(image[50, 50] - (0.8 - 0.55)) < 1e-6  # overlap is not darker
