"""The silhouette's shortcuts give, bit for bit, what the plain computation gives.

``plain_silhouette`` below is the straightforward pipeline written out without any of
them: every face's facing test, the drawing sampled on (N, 2) arrays, all 25 candidates of
each contour cell measured. ``mesh_silhouette`` (facing references, per-coordinate drawing,
only the filled candidates measured) must return the same arrays, on the demo's and the
real components, for steps from a thousandth of a millimetre to whole-pose jumps, as the
matcher makes them, in two views."""
import dataclasses

import cv2
import numpy as np
import pytest

from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import rotation_matrix
from fluorogui.core.projection.silhouette import _nearby_segments, _segment_cells, _snap, mesh_silhouette
from fluorogui.simulation.phantoms import femoral_component_mesh
from fluorogui.simulation.protocols import dual_orthogonal_views, flexion_pose


def plain_cells(segments, shape):
    P0, d = segments[:, 0], segments[:, 1] - segments[:, 0]
    n = np.floor(np.maximum(np.abs(d[:, 0]), np.abs(d[:, 1]))).astype(np.int64) + 2
    seg = np.repeat(np.arange(len(segments)), n)
    k = np.arange(len(seg)) - np.repeat(np.cumsum(n) - n, n)
    at = P0[seg] + (k / np.repeat(n - 1, n))[:, None] * d[seg]
    drawn = np.full(shape, -1, np.int32)
    drawn[np.floor(at[:, 1] + 0.5).astype(np.int64), np.floor(at[:, 0] + 0.5).astype(np.int64)] = seg
    return drawn


def drawn_one_by_one(segments, shape):
    """``plain_cells`` with its samples written one after the other: the last drawn stays."""
    drawn = np.full(shape, -1, np.int32)
    for s, (a, b) in enumerate(segments):
        n = int(np.floor(np.abs(b - a).max())) + 2
        for k in range(n):
            x, y = a + (k / (n - 1)) * (b - a)
            drawn[int(np.floor(y + 0.5)), int(np.floor(x + 0.5))] = s
    return drawn


def plain_nearby(drawn, cells):
    off = np.arange(-2, 3)
    dr, dc = (g.ravel() for g in np.meshgrid(off, off, indexing="ij"))
    rows = np.clip(cells[:, 1:2] + dr, 0, drawn.shape[0] - 1)
    cols = np.clip(cells[:, 0:1] + dc, 0, drawn.shape[1] - 1)
    return drawn[rows, cols]


def plain_snap(pts, cand, P0, P1):
    valid = cand >= 0
    cand = np.where(valid, cand, 0)
    ax, ay = P0[cand, 0], P0[cand, 1]
    abx, aby = P1[cand, 0] - ax, P1[cand, 1] - ay
    px, py = pts[:, 0:1], pts[:, 1:2]
    lam = np.clip(((px - ax) * abx + (py - ay) * aby) / np.maximum(abx * abx + aby * aby, 1e-12), 0.0, 1.0)
    qx, qy = ax + lam * abx, ay + lam * aby
    best = np.argmin(np.where(valid, (qx - px) ** 2 + (qy - py) ** 2, np.inf), axis=1)
    rows = np.arange(len(pts))
    return cand[rows, best], lam[rows, best], np.column_stack([qx[rows, best], qy[rows, best]])


def plain_silhouette(mesh, R, t, view, scale, spacing_px):
    s_model = R.T @ (view.source - t)
    front = mesh.face_normals @ s_model - mesh.face_offsets > 0
    edges = mesh.edges[front[mesh.edge_faces[:, 0]] != front[mesh.edge_faces[:, 1]]]
    if len(mesh.open_edges):
        edges = np.vstack([edges, mesh.open_edges])
    ends, e = np.unique(edges, return_inverse=True)
    e = e.reshape(edges.shape)
    uv, depth = view.project_with_depth(mesh.vertices[ends] @ R.T + t)
    segs = uv[e]
    origin = uv.min(0) - 3.0
    size = np.ceil((uv.max(0) - origin + 3.0) * scale).astype(int) + 1
    drawn = plain_cells((segs - origin) * scale, (size[1], size[0]))
    contours, _ = cv2.findContours((drawn >= 0).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    cells = max(contours, key=lambda c: cv2.contourArea(c) + len(c))[:, 0, :]
    if spacing_px:
        cells = cells[:: max(1, int(round(spacing_px * scale)))]
    sid, lam, p = plain_snap(cells / scale + origin, plain_nearby(drawn, cells), segs[:, 0], segs[:, 1])
    keep = np.r_[True, np.any(np.abs(np.diff(p, axis=0)) > 1e-9, axis=1)]
    sid, lam, p = sid[keep], lam[keep], p[keep]
    wa, wb = depth[e[sid, 0]], depth[e[sid, 1]]
    s3 = lam * wa / np.maximum(wb - lam * (wb - wa), 1e-12)
    va, vb = mesh.vertices[edges[sid, 0]], mesh.vertices[edges[sid, 1]]
    return p, va + s3[:, None] * (vb - va), segs


def walk(mesh, views, start, rng, steps):
    """``mesh_silhouette`` against ``plain_silhouette`` along a random walk of poses: steps
    of 0.001 to 30 mm (a third of that in degrees), now and then a jump back to the start,
    each pose seen in every view at the matcher's resolutions."""
    pose = start.copy()
    for k in range(steps):
        if k % 25 == 24:
            pose = start.copy()  # back near references made long ago
        size = 10 ** rng.uniform(-3, 1.5)
        pose = pose + np.r_[rng.normal(0, size, 3), rng.normal(0, size / 3, 3)]
        R = rotation_matrix(*pose[3:])
        for view in views:
            scale, spacing = [(2.0, 1.0), (2.0, None), (1.0, 2.0), (2.0, 4.0)][k % 4]
            got = mesh_silhouette(mesh, R, pose[:3], view, scale=scale, spacing_px=spacing)
            want = plain_silhouette(dataclasses.replace(mesh), R, pose[:3], view, scale, spacing)
            assert np.array_equal(got.points_px, want[0]), k
            assert np.array_equal(got.model_points, want[1]), k
            assert np.array_equal(got.segments_px, want[2]), k


def test_demo_silhouettes_are_the_plain_computation_bit_for_bit():
    v, f = femoral_component_mesh()
    walk(prepare_mesh(v, f), dual_orthogonal_views(), flexion_pose(v, 45.0), np.random.default_rng(5), 60)


@pytest.mark.parametrize("component", ["femoral", "tibial"])
def test_real_silhouettes_are_the_plain_computation_bit_for_bit(biplane, component):
    views, _, ref, meshes = biplane
    walk(meshes[component], views, ref[("51", component)], np.random.default_rng(7), 40)


def test_drawing_gathering_and_snapping_are_the_plain_ones_on_random_segments():
    rng = np.random.default_rng(11)
    for trial in range(30):
        n = int(rng.integers(1, 400))
        segments = rng.uniform(0, 60, (n, 2, 2))
        segments[: n // 10, 1] = segments[: n // 10, 0]  # zero-length ones
        segments[n // 10: n // 5, 1] = segments[n // 10: n // 5, 0] + rng.normal(0, 1e-7, (n // 5 - n // 10, 2))
        drawn = _segment_cells(segments, (62, 62))
        assert np.array_equal(drawn, plain_cells(segments, (62, 62))), trial
        assert np.array_equal(drawn, drawn_one_by_one(segments, (62, 62))), trial
        rows, cols = np.nonzero(drawn >= 0)
        cells = np.column_stack([cols, rows])[rng.permutation(len(rows))[:200]]  # at the border too
        cand = _nearby_segments(drawn, cells)
        assert np.array_equal(cand, plain_nearby(drawn, cells)), trial
        inner = cells[(cells.min(1) >= 2) & (cells.max(1) <= 59)]
        assert np.array_equal(_nearby_segments(drawn, inner), plain_nearby(drawn, inner)), trial
        pts = cells + rng.uniform(-0.5, 0.5, cells.shape)
        for got, want in zip(_snap(pts, cand, segments[:, 0], segments[:, 1]),
                             plain_snap(pts, cand, segments[:, 0], segments[:, 1])):
            assert np.array_equal(got, want), trial


def test_snap_takes_the_first_of_equally_near_candidates_as_argmin_does():
    """Points on the shared ends of a polyline's segments, candidates repeated and in every
    order: several candidates at the same distance, the first in the row wins; with a NaN
    segment, the first NaN (np.argmin's choice)."""
    rng = np.random.default_rng(5)
    vertices = np.cumsum(rng.integers(-3, 4, (40, 2)), axis=0).astype(float)
    P0, P1 = vertices[:-1], vertices[1:]
    pts = np.vstack([vertices[1:-1], vertices[1:-1] + 0.5, vertices[1:-1] + rng.uniform(-1, 1, (38, 2))])
    cand = rng.integers(-1, len(P0), (len(pts), 25))
    cand[:, 0] = np.tile(np.arange(38), 3)  # a filled candidate in every row
    cand[:, 7] = cand[:, 0] + 1  # and the other segment at the same vertex
    cand[:, 3] = cand[:, 0]  # repeated
    for got, want in zip(_snap(pts, cand, P0, P1), plain_snap(pts, cand, P0, P1)):
        assert np.array_equal(got, want)
    P0 = P0.copy()
    P0[[3, 11]] = np.nan
    for got, want in zip(_snap(pts, cand, P0, P1), plain_snap(pts, cand, P0, P1)):
        assert np.array_equal(got, want, equal_nan=True)


def test_snap_refuses_a_point_without_candidates():
    P0, P1 = np.array([[0.0, 0.0]]), np.array([[1.0, 0.0]])
    with pytest.raises(ValueError):
        _snap(np.array([[0.5, 0.5], [0.2, 0.1]]), np.array([[0, -1], [-1, -1]]), P0, P1)


def plain_facing_edges(mesh, s_model):
    front = mesh.face_normals @ s_model - mesh.face_offsets > 0
    return np.flatnonzero(front[mesh.edge_faces[:, 0]] != front[mesh.edge_faces[:, 1]])


def test_face_edges_name_each_face_s_own_edges():
    from fluorogui.core.projection.mesh import face_edges

    v, f = femoral_component_mesh()
    keep = np.ones(len(f), bool)
    keep[::7] = False  # holes: some edges are left with one face
    for mesh in (prepare_mesh(v, f), prepare_mesh(v, f[keep])):
        fe = face_edges(mesh)
        assert fe.shape == mesh.faces.shape and not fe.flags.writeable
        for corner, (a, b) in enumerate([(1, 2), (2, 0), (0, 1)]):
            ends = np.sort(mesh.faces[:, [a, b]], axis=1)
            paired = fe[:, corner] >= 0
            assert np.array_equal(mesh.edges[fe[paired, corner]], ends[paired])
            assert np.all(np.any(mesh.edge_faces[fe[paired, corner]] == np.flatnonzero(paired)[:, None], axis=1))
            open_ends = {tuple(e) for e in mesh.open_edges.tolist()}
            assert all(tuple(e) in open_ends for e in ends[~paired].tolist())
        assert (fe < 0).any() == (len(mesh.open_edges) > 0)


def test_facing_edges_reuse_the_last_edge_set_while_no_face_turns():
    from fluorogui.core.projection.facing import facing_edges

    mesh = prepare_mesh(*femoral_component_mesh())
    s = np.array([30.0, -1000.0, 40.0])
    first = facing_edges(mesh, s)
    assert facing_edges(mesh, s + 1e-6) is first  # no plane passes within a nanometre of the source
    far = facing_edges(mesh, s + np.array([0.0, 0.0, 15.0]))  # faces turn: a new set, from the same reference
    assert far is not first and len(mesh.cache["facing"]) == 1
    assert np.array_equal(far.edges, mesh.edges[plain_facing_edges(mesh, s + np.array([0.0, 0.0, 15.0]))])
    assert facing_edges(mesh, s + np.array([0.0, 0.0, 15.0 + 1e-6])) is far
    assert not far.edges.flags.writeable and np.array_equal(far.ends[far.local], far.edges)


def test_facing_edges_shared_by_threads_are_the_plain_ones():
    import threading

    from fluorogui.core.projection.facing import facing_edges

    mesh = prepare_mesh(*femoral_component_mesh())
    wrong = []

    def walk_from(start, seed):
        rng = np.random.default_rng(seed)
        s = start.copy()
        for k in range(300):
            s = s + rng.normal(0, 10 ** rng.uniform(-3, 1), 3)
            if not np.array_equal(facing_edges(mesh, s).edges, mesh.edges[plain_facing_edges(mesh, s)]):
                wrong.append((seed, k))

    # two sources near each other, so the threads share references and their last states
    threads = [threading.Thread(target=walk_from, args=(np.array([0.0, -1000.0, 0.0]), seed)) for seed in (1, 2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert wrong == []
