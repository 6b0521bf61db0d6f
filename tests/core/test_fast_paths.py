"""The shortcuts that make the fast matcher cheaper give what the plain computation gives.

Each shortcut is checked against the straightforward version it replaced, on the values
themselves (bit for bit where the arithmetic is the same), so a speed-up cannot move a
matched pose."""
import numpy as np

from fluorogui.core.matching.fast import _polyline_normals, _times_skew
from fluorogui.core.projection.silhouette import _band_samples, _edge_samples, _segments_near_band


def _random_segments(rng, n, size):
    """Segments of 0-12 px (some off the canvas) on a (h, w) canvas at scale 2."""
    a = rng.uniform(-10, np.array(size[::-1]) / 2 + 10, (n, 2))
    b = a + rng.normal(0, 4, (n, 2))
    b[: n // 10] = a[: n // 10]  # zero-length segments
    return np.stack([a, b], axis=1)


def test_band_prefilter_keeps_exactly_the_samples_of_all_segments():
    rng = np.random.default_rng(3)
    scale, origin = 2.0, np.array([-4.0, -2.5])
    for trial in range(20):
        h, w = 120 + trial, 150
        band = np.zeros((h, w), np.uint8)
        band[rng.integers(0, h, 40), rng.integers(0, w, 40)] = 1
        band[h // 2, :] = 1  # a line across, so that long segments cross it
        segs = _random_segments(rng, 400, (h, w)) + origin
        P0, P1 = segs[:, 0], segs[:, 1]
        n_sub = np.clip(np.ceil(np.sqrt(((P1 - P0) ** 2).sum(1)) / 2.0).astype(int), 1, 400)
        every = np.arange(len(segs))
        which = _segments_near_band(segs, band, origin, scale)
        assert len(which) < len(segs)  # it does leave segments out
        full, full_id = _band_samples(P0, P1, n_sub, band, origin, scale, every)
        kept, kept_id = _band_samples(P0, P1, n_sub, band, origin, scale, which)
        assert np.array_equal(full, kept) and np.array_equal(full_id, kept_id)


def test_edge_samples_run_end_to_end_every_two_px_at_most():
    P0, P1 = np.array([[0.0, 0.0], [5.0, 5.0]]), np.array([[3.0, 4.0], [5.0, 5.0]])
    n_sub = np.clip(np.ceil(np.linalg.norm(P1 - P0, axis=1) / 2.0).astype(int), 1, 400)
    samples, seg_id = _edge_samples(P0, P1, n_sub, np.arange(2))
    assert seg_id.tolist() == [0, 0, 0, 0, 1, 1]
    assert np.allclose(samples[:4], [[0, 0], [1, 4 / 3], [2, 8 / 3], [3, 4]])


def test_polyline_normals_at_indices_are_the_full_ones_there():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(300, 2))
    at = np.r_[0, 299, rng.integers(0, 300, 50)]
    assert np.array_equal(_polyline_normals(points, at), _polyline_normals(points)[at])
    angles = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    circle = np.column_stack([np.cos(angles), np.sin(angles)])
    assert np.allclose(np.abs(np.sum(_polyline_normals(circle) * circle, axis=1)), 1.0)


def test_times_skew_is_the_row_times_the_cross_product_matrix():
    rng = np.random.default_rng(1)
    a, v = rng.normal(size=(200, 3)), rng.normal(size=(200, 3))
    skew = np.zeros((200, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    skew -= skew.transpose(0, 2, 1)
    assert np.allclose(_times_skew(a, v), np.einsum("ik,ikl->il", a, skew), rtol=0, atol=1e-14)
    assert np.allclose(_times_skew(a, v), np.cross(a, v), rtol=0, atol=1e-14)


def test_facing_references_give_the_silhouette_edges_of_a_fresh_computation():
    import dataclasses

    from fluorogui.core.projection.mesh import prepare_mesh
    from fluorogui.core.projection.pose import rotation_matrix
    from fluorogui.core.projection.silhouette import FACING_REFERENCES, silhouette_edges
    from fluorogui.simulation.phantoms import femoral_component_mesh

    mesh = prepare_mesh(*femoral_component_mesh())
    rng = np.random.default_rng(2)
    source = np.array([0.0, -1000.0, 0.0])
    pose = np.array([0.0, 0.0, 0.0, 20.0, -30.0, 10.0])
    made = []  # every facing reference made (kept alive, so identity is meaningful)
    for k in range(150):
        step = 10 ** rng.uniform(-3, 1.5)  # 0.001 to 30 mm / a third of that in degrees
        pose = pose + np.r_[rng.normal(0, step, 3), rng.normal(0, step / 3, 3)]
        R = rotation_matrix(*pose[3:])
        cached = silhouette_edges(mesh, R, pose[:3], source)
        if not any(ref is mesh.cache["facing"][0] for ref in made):
            made.append(mesh.cache["facing"][0])
        fresh = silhouette_edges(dataclasses.replace(mesh), R, pose[:3], source)  # a copy starts without references
        assert np.array_equal(cached, fresh), k
    assert len(mesh.cache["facing"]) <= FACING_REFERENCES
    assert 10 < len(made) < 120  # most small moves reuse a reference, large ones make new ones


def test_no_facing_reference_for_a_source_close_to_the_mesh():
    from fluorogui.core.projection.mesh import prepare_mesh
    from fluorogui.core.projection.silhouette import silhouette_edges
    from fluorogui.simulation.phantoms import sphere_mesh

    mesh = prepare_mesh(*sphere_mesh(40.0, subdivisions=3))
    near_source = np.array([0.0, -45.0, 0.0])  # 25 mm off a 20 mm sphere: most planes pass within the margin
    edges = silhouette_edges(mesh, np.eye(3), np.zeros(3), near_source)
    assert "facing" not in mesh.cache
    silhouette_edges(mesh, np.eye(3), np.zeros(3), np.array([0.0, -1000.0, 0.0]))
    assert len(mesh.cache["facing"]) == 1
    # the edges seen from close by are a silhouette loop: every vertex on it has two of them
    assert len(edges) > 10 and np.all(np.bincount(edges.ravel())[np.unique(edges)] == 2)
