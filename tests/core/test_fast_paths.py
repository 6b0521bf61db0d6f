"""The shortcuts that make the fast matcher cheaper give what the plain computation gives.

Each shortcut is checked against the straightforward version it replaced, on the values
themselves (bit for bit where the arithmetic is the same), so a speed-up cannot move a
matched pose; the silhouette's drawing and snapping against what they promise."""
import numpy as np

from fluorogui.core.matching.fast import _polyline_normals, _times_skew
from fluorogui.core.projection.silhouette import _segment_cells, _snap


def test_segment_cells_are_eight_connected_from_end_to_end():
    rng = np.random.default_rng(3)
    segments = np.stack([rng.uniform(5, 95, (300, 2)), rng.uniform(5, 95, (300, 2))], axis=1)
    segments[:30, 1] = segments[:30, 0]  # zero-length segments
    for i, seg in enumerate(segments):
        drawn = _segment_cells(seg[None], (100, 100))
        rows, cols = np.nonzero(drawn == 0)
        ends = np.floor(seg + 0.5).astype(int)
        assert drawn[ends[0, 1], ends[0, 0]] == 0 and drawn[ends[1, 1], ends[1, 0]] == 0
        # walking from one end through 8-neighbours reaches every drawn cell
        cells = set(zip(rows.tolist(), cols.tolist()))
        todo, seen = [(ends[0, 1], ends[0, 0])], set()
        while todo:
            r, c = todo.pop()
            if (r, c) in seen or (r, c) not in cells:
                continue
            seen.add((r, c))
            todo += [(r + dr, c + dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1)]
        assert seen == cells, i
        # and no cell's centre lies farther than half a diagonal from the segment
        p = np.column_stack([cols, rows]).astype(float)
        d = seg[1] - seg[0]
        lam = np.clip(((p - seg[0]) @ d) / max(d @ d, 1e-12), 0, 1)
        assert np.linalg.norm(seg[0] + lam[:, None] * d - p, axis=1).max() <= np.sqrt(0.5) + 1e-9


def test_snap_takes_the_nearest_candidate_segment_and_skips_empty_cells():
    P0 = np.array([[0.0, 0.0], [0.0, 1.0], [5.0, 5.0]])
    P1 = np.array([[10.0, 0.0], [10.0, 1.0], [6.0, 5.0]])
    pts = np.array([[3.0, 0.2], [4.0, 0.9], [5.5, 4.0]])
    cand = np.array([[-1, 0, 1], [0, -1, 1], [2, -1, -1]])
    seg, lam, at = _snap(pts, cand, P0, P1)
    assert seg.tolist() == [0, 1, 2]
    assert np.allclose(at, [[3.0, 0.0], [4.0, 1.0], [5.5, 5.0]]) and np.allclose(lam, [0.3, 0.4, 0.5])


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

    from fluorogui.core.projection.facing import FACING_REFERENCES
    from fluorogui.core.projection.mesh import prepare_mesh
    from fluorogui.core.projection.pose import rotation_matrix
    from fluorogui.core.projection.silhouette import silhouette_edges
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


def test_jacobian_rows_equal_the_stacked_form():
    """``_FastEvaluation._add`` writes [nJ | -(nJ x (X - c)) / rho] in place: the same bits
    as stacking the two blocks."""
    from fluorogui.core.matching.fast import _FastEvaluation

    rng = np.random.default_rng(7)
    nJ, X, c = rng.normal(0, 3, (500, 3)), rng.normal(0, 40, (500, 3)), rng.normal(0, 40, 3)
    ev = _FastEvaluation.__new__(_FastEvaluation)
    ev.r, ev.J, ev.w = [], [], []
    ev._add(rng.normal(size=500), nJ, X, c, rho=31.7)
    np.testing.assert_array_equal(ev.J[0], np.hstack([nJ, -_times_skew(nJ, X - c) / 31.7]))
