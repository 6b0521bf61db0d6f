"""find_components: implants placed with no start (or near a prediction), and an honest
"not found" when that cannot be done, on rendered images with known poses. (Its speed and
how soon it stops when cancelled: benchmarks/bench_budgets.py and bench_find.py.)"""
import cv2
import numpy as np
import pytest
from scipy.spatial import cKDTree

from fluorogui.core.cancel import Cancelled
from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import (
    angles_from_matrix,
    pose_error,
    rotation_matrix,
    rotvec_matrix,
    transform_points,
)
from fluorogui.core.search import find
from fluorogui.core.search import shape_search as ss
from fluorogui.core.search.find import Placement, find_components, near_candidates
from fluorogui.simulation.demo import anatomy_meshes, demo_views, knee_bend_poses, posed_anatomy, render_view
from fluorogui.simulation.phantoms import femoral_component_mesh, tibial_component_mesh
from fluorogui.simulation.render import render_fluoro


@pytest.fixture(scope="module")
def scene():
    """One demo frame rendered in memory: both components over bone and soft tissue."""
    raw = {"femoral": femoral_component_mesh(), "tibial": tibial_component_mesh()}
    meshes = {name: prepare_mesh(*mesh) for name, mesh in raw.items()}
    views = demo_views(1024)
    truth = knee_bend_poses(30.0, 0.6)
    anatomy = posed_anatomy(truth, anatomy_meshes())
    posed = [(transform_points(truth[name], v), f) for name, (v, f) in raw.items()]
    rng = np.random.default_rng(3)
    images = [render_view(view, [posed], anatomy, rng) for view in views]
    empty = [render_view(view, [], anatomy, rng) for view in views]  # the same knee without implants
    return images, views, meshes, truth, empty


@pytest.fixture(scope="module")
def found(scene):
    images, views, meshes, _, _ = scene
    calls = []
    out = find_components(images, views, meshes, progress=lambda f, text: calls.append((f, text)))
    return out, calls


def _errors(pose, truth):
    e = np.abs(pose_error(pose, truth))
    return e[:3].max(), e[3:].max()


@pytest.mark.slow
def test_finds_both_components_from_nothing(scene, found):
    _, views, meshes, truth, _ = scene
    out, _ = found
    assert set(out) == {"femoral", "tibial"}
    for name, p in out.items():
        assert isinstance(p, Placement) and p.component == name
        assert p.found and p.reason == "", p.reason
        mm, deg = _errors(p.pose, truth[name])
        # measured: femoral 0.0034 mm / 0.0078 deg, tibial 0.0016 mm / 0.040 deg
        assert mm < 0.0065 and deg < 0.08, (name, mm, deg)
        assert len(p.iou) == 2 and min(p.iou) > 0.982, p.iou  # measured 0.9956 / 0.9956, 0.9910 / 0.9910
        assert len(p.per_view_mean_mm) == 2 and max(p.per_view_mean_mm) < 0.056  # measured 0.022-0.028 mm
        assert p.objective_mm == pytest.approx(sum(p.per_view_mean_mm))
        assert min(p.edge_score) > 0.988 and p.seconds > 0  # measured 0.994 at least


@pytest.mark.slow
def test_progress_runs_to_one(found):
    _, calls = found
    fractions = [f for f, _ in calls]
    assert len(calls) > 10 and fractions[0] == 0.0 and fractions[-1] == 1.0
    assert all(b >= a for a, b in zip(fractions, fractions[1:]))
    assert all(isinstance(text, str) and text for _, text in calls)


@pytest.mark.slow
def test_near_a_prediction(scene, found):
    images, views, meshes, truth, _ = scene
    rng = np.random.default_rng(7)
    near = {}
    for name, pose in truth.items():  # 5 mm and 15 degrees off, about the centroid
        R = rotvec_matrix(np.radians(15.0) * _unit(rng.normal(size=3))) @ rotation_matrix(*pose[3:])
        c = rotation_matrix(*pose[3:]) @ meshes[name].centroid + pose[:3] + 5.0 * _unit(rng.normal(size=3))
        near[name] = np.r_[c - R @ meshes[name].centroid, angles_from_matrix(R)]
    out = find_components(images, views, meshes, near=near)
    for name, p in out.items():
        assert p.found, p.reason
        mm, deg = _errors(p.pose, truth[name])
        assert mm < 0.0075 and deg < 0.08, (name, mm, deg)  # measured 0.0037 / 0.0016 mm, 0.0092 / 0.040 deg


@pytest.mark.slow
def test_says_so_when_nothing_is_there(scene, found):
    _, views, meshes, _, empty = scene
    out = find_components(empty, views, meshes)
    for name, p in out.items():
        assert not p.found and p.reason, name
        assert p.pose is None or max(p.per_view_mean_mm, default=np.inf) > 0.3


def test_can_be_cancelled(scene):
    images, views, meshes, _, _ = scene
    with pytest.raises(Cancelled):
        find_components(images, views, meshes, cancel=lambda: True)
    polls = []

    def cancel_later():  # cancel on the fifth poll, in the middle of the search
        polls.append(len(polls))
        return len(polls) >= 5

    with pytest.raises(Cancelled):
        find_components(images, views, meshes, cancel=cancel_later)
    assert len(polls) == 5  # stops at the poll that said so, asking no more


@pytest.mark.slow
def test_a_symmetric_part_is_ambiguous():
    """A plain box looks the same turned by 180 degrees: never a confident placement."""
    box = _box(40.0, 20.0, 10.0)
    mesh = prepare_mesh(*box)
    views = demo_views(1024)
    pose = np.array([5.0, -3.0, 10.0, 20.0, 30.0, 10.0])
    rng = np.random.default_rng(1)
    images = [render_fluoro(v, [(transform_points(pose, box[0]), box[1])], rng, blur_sigma_px=0.8) for v in views]
    p = find_components(images, views, {"box": mesh})["box"]
    assert not p.found and "apart fit equally well" in p.reason, p.reason
    assert p.pose is not None



# -- the pieces -----------------------------------------------------------------------------------
def test_decimated_mesh_keeps_the_silhouette(scene):
    _, views, meshes, truth, _ = scene
    mesh = meshes["femoral"]
    small = ss.decimate_mesh(mesh, 4000)
    assert 2500 < len(small.faces) < 6000 < len(mesh.faces)
    R = rotation_matrix(*truth["femoral"][3:])
    c = R @ mesh.centroid + truth["femoral"][:3]
    for view in views:
        masks = []
        for m in (mesh, small):
            pts = ss.outline(m, R, c, view, spacing_px=1.0)[0]
            canvas = np.zeros((1024, 1024), np.uint8)
            cv2.fillPoly(canvas, [np.round(pts).astype(np.int32)], 1)
            masks.append(canvas > 0)
        assert (masks[0] & masks[1]).sum() / (masks[0] | masks[1]).sum() > 0.97  # measured 0.9796, 0.9820


def test_templates_match_exact_outlines(scene):
    _, views, meshes, truth, _ = scene
    mesh = meshes["tibial"]
    lib = ss.shape_library(mesh)
    assert ss.shape_library(mesh) is lib  # cached
    rotations = np.stack([rotation_matrix(*a) for a in np.random.default_rng(2).uniform(-180, 180, (8, 3))])
    c = np.array([2.0, -4.0, -15.0])
    for view in views:
        pts, normals = ss.place_templates(lib, view, rotations, c)
        assert pts.shape == (8, 32, 2) and np.allclose(np.linalg.norm(normals, axis=2) > 0, True)
        for R, p in zip(rotations, pts):
            exact = ss.outline(mesh, R, c, view, spacing_px=1.0)[0]
            d = np.min(np.linalg.norm(p[:, None, :] - exact[None], axis=2), axis=1)
            # px: templates are ~4 degrees apart; a 70 mm part is ~230 px. Measured 0.50-2.19 px
            assert np.median(d) < 4.0


def test_edge_refinement_pulls_a_rough_pose_in(scene):
    images, views, meshes, truth, _ = scene
    mesh = meshes["femoral"]
    lib = ss.shape_library(mesh)
    maps = [ss.EdgeMaps(image) for image in images]
    R0 = rotation_matrix(*truth["femoral"][3:])
    c0 = R0 @ mesh.centroid + truth["femoral"][:3]
    right = np.mean(ss.pose_edge_score(lib.coarse, R0, c0, views, maps=maps))
    R = rotvec_matrix(np.radians([6.0, -5.0, 4.0])) @ R0
    c = c0 + np.array([3.0, -2.0, 2.0])
    assert np.mean(ss.pose_edge_score(lib.coarse, R, c, views, maps=maps)) < right - 0.32  # measured 0.358 vs 0.995
    R, c = ss.refine_on_edges(lib.coarse, views, maps, R, c=c)
    R, c = ss.refine_on_edges(lib.fine, views, maps, R, c=c, radii_px=(4, 3, 3))
    angle = np.degrees(np.arccos(np.clip((np.trace(R.T @ R0) - 1) / 2, -1, 1)))
    # measured 0.093 deg, 0.0096 mm
    assert angle < 0.185 and np.linalg.norm(c - c0) < 0.019, (angle, np.linalg.norm(c - c0))
    assert right > 0.99  # measured 0.995


def test_outline_nearest_vertices_as_a_balanced_tree_finds_them(scene, monkeypatch):
    """``outline`` finds each point's nearest model vertex with a quickly built tree
    (unbalanced, not compacted): the same vertices and distances as a default cKDTree, at
    poses about the right one of both components in both views."""
    _, views, meshes, truth, _ = scene
    made = []

    def tree(data, **kwargs):
        made.append((np.array(data), kwargs))
        return cKDTree(data, **kwargs)

    monkeypatch.setattr(ss, "cKDTree", tree)
    rng = np.random.default_rng(4)
    for name, mesh in meshes.items():
        coarse = ss.shape_library(mesh).coarse
        for _ in range(4):
            R = rotvec_matrix(np.radians(rng.normal(0, 8, 3))) @ rotation_matrix(*truth[name][3:])
            c = R @ mesh.centroid + truth[name][:3] + rng.normal(0, 3, 3)
            for view in views:
                made.clear()
                pts, _, model = ss.outline(coarse, R, c, view, spacing_px=3.0)
                (uv, kwargs), = made
                assert kwargs == {"balanced_tree": False, "compact_nodes": False}
                fast, default = cKDTree(uv, **kwargs).query(pts), cKDTree(uv).query(pts)
                assert np.array_equal(fast[0], default[0]) and np.array_equal(fast[1], default[1])
                assert len(model) == len(pts)


def test_edge_maps_are_the_plain_formula(scene):
    """``EdgeMaps`` makes its oriented scores in place: every level and direction the
    plain ``rint(clip((gx cos t + gy sin t) * 127 / ref, -127, 127))``, on both views."""
    images = scene[0]
    for image in images:
        maps = ss.EdgeMaps(image, ss.field_of_view(image))
        img = ss.to_unit_float(image)
        for name, (_, sigma) in ss.LEVELS.items():
            level_scale, flat, H, W, _ = maps.levels[name]
            small = cv2.resize(img, None, fx=level_scale, fy=level_scale, interpolation=cv2.INTER_AREA)
            blurred = cv2.GaussianBlur(small, (0, 0), sigma)
            gx, gy = cv2.Sobel(blurred, cv2.CV_32F, 1, 0) / 8.0, cv2.Sobel(blurred, cv2.CV_32F, 0, 1) / 8.0
            ref = maps.g_ref * (level_scale / maps.work)
            planes = flat.reshape(ss.N_BINS, H, W)
            for k, t in enumerate(2 * np.pi * np.arange(ss.N_BINS) / ss.N_BINS):
                plain = np.rint(np.clip((gx * np.cos(t) + gy * np.sin(t)) * (127.0 / ref), -127.0, 127.0))
                assert np.array_equal(planes[k, ss.PAD:-ss.PAD, ss.PAD:-ss.PAD], plain.astype(np.int8))
            assert not planes[:, :ss.PAD].any() and not planes[:, :, -ss.PAD:].any()


def test_edge_map_indices_are_the_plain_formula(scene):
    """``EdgeMaps.index`` works in place and takes the direction bin with a mask: the same
    indices as the plain formula, for template outlines in every direction, on both
    levels, with points far outside the map (clipped) among them."""
    images, views, meshes, _, _ = scene
    maps = ss.EdgeMaps(images[0])
    lib = ss.shape_library(meshes["tibial"])
    rotations = find._grid(600)
    points, normals = ss.place_templates(lib, views[0], rotations, np.array([2.0, -4.0, -15.0]))
    points[::7] *= 3.0  # off the map
    for level in ss.LEVELS:
        scale, _, H, W, (h, w) = maps.levels[level]
        q = points * scale + (scale - 1.0) / 2.0
        x = np.clip(np.rint(q[..., 0]), -ss.PAD // 2, w + ss.PAD // 2).astype(np.int64) + ss.PAD
        y = np.clip(np.rint(q[..., 1]), -ss.PAD // 2, h + ss.PAD // 2).astype(np.int64) + ss.PAD
        turn = np.arctan2(normals[..., 1], normals[..., 0]) * (ss.N_BINS / (2 * np.pi))
        b = np.rint(turn).astype(np.int64) % ss.N_BINS
        assert np.array_equal(maps.index(level, points, normals), (b * H + y) * W + x)


def test_segments_are_drawn_as_opencv_draws_them(scene):
    """``shape_search.draw_segments`` sets the very pixels ``cv2.polylines`` (1 px, LINE_8,
    4 fraction bits) sets: random segments of every slope and length (points, axis-aligned
    and diagonal ones, ends on half pixels among them), the silhouette edges of outlines,
    and ends off the canvas (left to OpenCV)."""
    rng = np.random.default_rng(8)

    def both(segments, shape):
        plain, ours = np.zeros(shape, np.uint8), np.zeros(shape, np.uint8)
        cv2.polylines(plain, segments, False, 1, 1, cv2.LINE_8, 4)
        ss.draw_segments(ours, segments)
        assert np.array_equal(plain, ours)

    for trial in range(3000):
        n = int(rng.integers(1, 40))
        segments = rng.integers(0, 60 * 16, size=(n, 2, 2))
        kind = trial % 5
        if kind == 1:  # short
            segments[:, 1] = segments[:, 0] + rng.integers(-100, 100, size=(n, 2))
        elif kind == 2:  # axis-aligned and diagonal
            d = rng.integers(-100, 100, size=n)
            segments[:, 1, 0] = segments[:, 0, 0] + d * rng.integers(0, 2, size=n)
            segments[:, 1, 1] = segments[:, 0, 1] + d * rng.integers(-1, 2, size=n)
        elif kind == 3:  # ends on and about half pixels
            segments = segments // 16 * 16 + rng.choice([0, 7, 8, 9, 15], size=segments.shape)
        elif kind == 4:  # points
            segments[:, 1] = segments[:, 0]
        both(np.clip(segments, 0, 60 * 16 - 1).astype(np.int32), (64, 64))
    both(np.array([[[-40, 20], [300, 500]]], np.int32), (24, 24))  # off the canvas
    _, views, meshes, truth, _ = scene
    for name, mesh in meshes.items():
        coarse = ss.shape_library(mesh).coarse
        R = rotation_matrix(*truth[name][3:])
        t = truth[name][:3]
        for view in views:
            found = ss.facing_edges(coarse, R.T @ (view.source - t))
            uv = view.project(coarse.vertices[found.ends] @ R.T + t)
            lo = np.floor(uv.min(0)) - 2.0
            size = (np.ceil(uv.max(0) - lo) + 3).astype(int)
            both(np.round((uv - lo) * 16).astype(np.int32)[found.local], (size[1], size[0]))


def _unit(v):
    return v / np.linalg.norm(v)


def _box(a, b, c):
    v = np.array([[x, y, z] for x in (-a / 2, a / 2) for y in (-b / 2, b / 2) for z in (-c / 2, c / 2)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [t for q in quads for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))]
    return v, np.array(faces)


def test_near_candidates_are_the_poses_a_canny_fit_would_start_from(scene):
    """Tracking recovery's near search (``near_candidates``) stops before the Canny fit: the
    match from each candidate makes it. The best candidate lies close enough for that."""
    images, views, meshes, truth, empty = scene
    rng = np.random.default_rng(7)
    for name, pose in truth.items():  # 5 mm and 15 degrees off, about the centroid
        R = rotvec_matrix(np.radians(15.0) * _unit(rng.normal(size=3))) @ rotation_matrix(*pose[3:])
        c = rotation_matrix(*pose[3:]) @ meshes[name].centroid + pose[:3] + 5.0 * _unit(rng.normal(size=3))
        start = np.r_[c - R @ meshes[name].centroid, angles_from_matrix(R)]
        poses = near_candidates(images, views, meshes[name], start)
        assert 1 <= len(poses) <= 2
        mm, deg = _errors(poses[0], truth[name])
        assert mm < 0.035 and deg < 0.19, (name, mm, deg)  # measured 0.0087 / 0.017 mm, 0.095 / 0.019 deg
        assert near_candidates(empty, views, meshes[name], start) == []
    with pytest.raises(ValueError, match="two views"):  # (single-plane recovery does not search)
        near_candidates(images[:1], views[:1], meshes["tibial"], truth["tibial"])


def test_a_frames_edge_maps_are_made_once_and_searches_find_the_same(scene):
    """Recovery searches each component of a frame on the same images: their edge maps are
    made once per set of image arrays (``shape_search.edge_maps_of``), and a search gives the
    same poses with them as with maps made afresh."""
    images, views, meshes, truth, empty = scene
    fovs, maps = ss.edge_maps_of(images)
    again = ss.edge_maps_of(list(images))  # another list of the same arrays
    assert all(a is b for a, b in zip(maps, again[1])) and all(a is b for a, b in zip(fovs, again[0]))
    copies = [image.copy() for image in images]  # equal images, other arrays: made again
    fresh = ss.edge_maps_of(copies)[1]
    assert not any(a is b for a, b in zip(maps, fresh))
    assert all(np.array_equal(a.levels["fine"][1], b.levels["fine"][1]) for a, b in zip(maps, fresh))
    start = truth["tibial"] + np.array([2.0, -2.0, 1.0, 4.0, -3.0, 2.0])
    cached = near_candidates(images, views, meshes["tibial"], start)  # (after copies: made again)
    assert all(a is not b for a, b in zip(ss.edge_maps_of(images)[1], fresh))
    twice = near_candidates(images, views, meshes["tibial"], start)
    assert len(cached) >= 1 and all(np.array_equal(a, b) for a, b in zip(cached, twice))


def test_far_from_all_answers_as_the_one_by_one_loop():
    """``shape_search.far_from_all`` takes the distances all at once: the same answer as
    ``all(norm(p - q) > limit ...)`` (points exactly at the limit, NaN, none), in 2D and 3D."""
    rng = np.random.default_rng(7)
    for trial in range(3000):
        dim = 2 + trial % 2
        points = [rng.normal(size=dim) * 10 for _ in range(rng.integers(0, 6))]
        p = rng.normal(size=dim) * 10
        if points and trial % 3 == 0:
            points[0] = p + np.eye(dim)[0] * 12.0  # on the limit
        if points and trial % 7 == 0:
            points[-1] = np.full(dim, np.nan)
        loop = all(np.linalg.norm(p - q) > 12.0 for q in points)
        assert ss.far_from_all(p, points, 12.0) == loop
        assert ss.far_from_all(p, np.array(points).reshape(-1, dim), 12.0) == loop


def test_dark_regions_made_once_give_both_rounds_their_points(scene):
    """*Find implants*' two rounds of position hypotheses read one ``dark_levels`` per image:
    the same centroids and depth peaks as dark regions made afresh for each round."""
    images, views, meshes, truth, empty = scene
    fovs = ss.edge_maps_of(images)[0]
    for image, fov in zip(images, fovs):
        levels = ss.dark_levels(image, fov)
        assert len(levels.regions) >= 10
        for peaks in (0, 4):
            afresh = ss.dark_region_points(image, fov, max_peaks=peaks)
            shared = ss.dark_region_points(image, fov, max_peaks=peaks, levels=levels)
            assert len(afresh[0]) >= 3 and (len(afresh[1]) >= 1) == (peaks > 0)
            for a, b in zip(afresh, shared):
                assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))


def _distinct_one_by_one(order, rotations, k, min_deg):
    """The rule ``find._distinct`` keeps: each of ``order`` farther than ``min_deg`` from all kept before it."""
    out = []
    for i in order:
        if all(find._angle_deg(rotations[i], rotations[j]) > min_deg for j in out):
            out.append(int(i))
            if len(out) == k:
                break
    return out


def test_distinct_keeps_what_the_one_by_one_rule_keeps():
    """``find._distinct`` removes near duplicates of each kept orientation all at once: the
    same candidates, in the same order, as the one-by-one rule, on the rotations the search
    scans (the 4000-orientation grid, the 5-degree steps about its best) in many orders,
    with rotations at and exactly on the limit of others, and fewer than ``k`` distinct."""
    rng = np.random.default_rng(5)
    grid = find._grid(4000)
    for trial in range(24):
        base = grid[rng.choice(len(grid), 300, replace=False)]
        local = np.matmul(find._LOCAL_STEPS[None], base[:40][:, None]).reshape(-1, 3, 3)
        axes = rng.normal(size=(20, 3))
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        min_deg = (20.0, 8.0, 45.0)[trial % 3]
        on_limit = np.stack([rotvec_matrix(np.radians(min_deg) * a) @ base[0] for a in axes])
        if trial % 4 < 2:  # the limit the very angle of one of them: not farther than it
            min_deg = find._angle_deg(base[0], on_limit[0])
        rotations = np.concatenate([base, local, on_limit])
        order = rng.permutation(len(rotations))
        if trial % 2:
            order = np.r_[0, order[order != 0]]  # base[0] kept first: those on its limit are judged
        for k in (1, 6, 40) if trial % 6 else (6, 5000):
            assert find._distinct(order, rotations, k, min_deg) == _distinct_one_by_one(order, rotations, k, min_deg)
    same = np.repeat(grid[:1], 5, axis=0)  # fewer distinct than asked for
    assert find._distinct(np.arange(5), same, 3) == [0]
