"""The generated knee-bend sequence: loadable, truth exact and reproducible, images agree with it.

The image checks project the mesh vertices with our own pinhole arithmetic and fill the
projected triangles with OpenCV, so they share nothing with the renderer under test
(``fluorogui.simulation.render``) or the matcher's silhouette code.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from fluorogui.core.projection.pose import pose_to_matrix
from fluorogui.io.images import read_image
from fluorogui.io.importer import detect_biplane_folder
from fluorogui.io.meshes.read import load_mesh
from fluorogui.io.project.document import load_project
from fluorogui.simulation import knee_bend as synthetic
from fluorogui.simulation.demo import FIELD_RADIUS_FRACTION, write_stl
from fluorogui.simulation.knee_bend import (
    MeshTopology,
    build_knee_sequence,
    flexion_schedule,
    knee_bend_truth,
    metal_coverage,
)
from fluorogui.simulation.phantoms import femoral_component_mesh, tibial_component_mesh
from fluorogui.simulation.render import coverage_of_meshes

REAL_MODELS = Path(__file__).resolve().parents[3] / "shared" / "data" / "biplane-tka" / "models"
FRAMES = 3
SIZE = 256
START = 7


@pytest.fixture(scope="module")
def phantom_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("meshes")
    paths = {}
    for component, mesh in (("femoral", femoral_component_mesh()), ("tibial", tibial_component_mesh())):
        paths[component] = folder / f"{component}.stl"
        write_stl(paths[component], *mesh)
    return paths


@pytest.fixture(scope="module")
def built(tmp_path_factory, phantom_files):
    folder = tmp_path_factory.mktemp("knee")
    return build_knee_sequence(folder, phantom_files["femoral"], phantom_files["tibial"], frames=FRAMES,
                               image_size=SIZE, seed=5, start_frame=START)


# -- independent projection ---------------------------------------------------------------
def pinhole(view, points):
    """Pinhole projection written out from the View fields (docs/developer/conventions.rst), not View.project."""
    d = np.asarray(points, dtype=float) - view.source
    depth = d @ view.normal
    u = view.principal_point[0] + view.distance / view.pitch[0] * (d @ view.e_u) / depth
    v = view.principal_point[1] + view.distance / view.pitch[1] * (d @ view.e_v) / depth
    return np.column_stack([u, v])


def posed(pose, vertices):
    T = pose_to_matrix(pose)
    return vertices @ T[:3, :3].T + T[:3, 3]


def filled_mask(view, pose, mesh) -> np.ndarray:
    """Pixels whose centre the projected mesh covers (OpenCV polygon fill, 1/16 px vertices)."""
    vertices, faces = mesh
    uv = pinhole(view, posed(pose, vertices))
    width, height = view.image_size
    mask = np.zeros((height, width), np.uint8)
    polygons = np.round(uv[faces] * 16).astype(np.int32)
    cv2.fillPoly(mask, list(polygons), 1, lineType=cv2.LINE_8, shift=4)
    return mask


def ring(mask, inner_px: int, outer_px: int, outside: bool) -> np.ndarray:
    kernel = lambda r: np.ones((2 * r + 1, 2 * r + 1), np.uint8)  # noqa: E731
    if outside:
        return (cv2.dilate(mask, kernel(outer_px)) > 0) & ~(cv2.dilate(mask, kernel(inner_px)) > 0)
    return (cv2.erode(mask, kernel(inner_px)) > 0) & ~(cv2.erode(mask, kernel(outer_px)) > 0)


def edge_contrast(image, view, poses, meshes) -> float:
    """Mean intensity just outside the union of the outlines minus just inside it."""
    union = np.zeros(image.shape, np.uint8)
    for component, mesh in meshes.items():
        union |= filled_mask(view, poses[component], mesh)
    return float(image[ring(union, 1, 2, True)].mean() - image[ring(union, 1, 2, False)].mean())


def own_edge_contrast(image, view, pose, mesh, elsewhere) -> float:
    """The same for one component's outline, leaving out where it runs over ``elsewhere``."""
    mask = filled_mask(view, pose, mesh)
    free = ~(cv2.dilate(elsewhere, np.ones((7, 7), np.uint8)) > 0)
    return float(image[ring(mask, 1, 2, True) & free].mean() - image[ring(mask, 1, 2, False) & free].mean())


# -- the project ----------------------------------------------------------------------------
def test_project_loads_with_views_models_and_no_poses(built, phantom_files):
    project = load_project(built)
    frames = list(range(START, START + FRAMES))
    assert project.frames == frames and project.poses == {}
    assert [len(s.paths) for s in project.sequences] == [FRAMES, FRAMES]
    for sequence in project.sequences:
        assert all(p.is_file() and p.name == f"frame_{f:04d}.png" for p, f in zip(sequence.paths, frames))
    assert {m.component: m.mesh_path for m in project.models} == phantom_files  # pointed at, not copied
    first, second = project.views
    angle = np.degrees(np.arccos(first.normal @ second.normal))
    assert 55.0 <= angle <= 75.0  # not orthogonal
    assert sorted(round(v.distance) for v in project.views) == [1100, 1250]
    tilts = [abs(np.degrees(np.arcsin(v.normal[2]))) for v in project.views]
    assert max(tilts) >= 8.0  # one view well out of the horizontal plane
    for view in project.views:
        assert view.image_size == (SIZE, SIZE)
        assert view.pitch[0] * SIZE / 1024 == pytest.approx(0.3)
        offset = np.subtract(view.principal_point, (SIZE - 1) / 2.0) * 1024 / SIZE
        assert np.linalg.norm(offset) > 5.0  # principal point off centre
    recipe = project.settings["synthetic"]
    assert (recipe["seed"], recipe["side"], recipe["frames"], recipe["start_frame"]) == (5, "right", FRAMES, START)
    assert [v["name"] for v in recipe["views"]] == ["cam1", "cam2"]
    found = detect_biplane_folder(built.parent)
    assert found is not None and found["pairs_csv"] == built.parent / "pairs.csv"
    assert [p.name for p in found["calibrations"]] == ["cam1.json", "cam2.json"]


def test_truth_is_stored_exactly_and_reproducible(built, phantom_files, tmp_path):
    project = load_project(built)
    truth = project.settings["truth"]
    assert list(truth) == [str(f) for f in project.frames]
    meshes = {c: load_mesh(p) for c, p in phantom_files.items()}
    expected = knee_bend_truth(meshes["femoral"][0], meshes["tibial"][0], flexion_schedule(FRAMES))
    for i, frame in enumerate(project.frames):
        for component in ("femoral", "tibial"):
            assert truth[str(frame)][component] == [float(x) for x in expected[i][component]]  # bit for bit
    again = build_knee_sequence(tmp_path / "again", phantom_files["femoral"], phantom_files["tibial"],
                                frames=FRAMES, image_size=SIZE, seed=5, start_frame=START)
    other = build_knee_sequence(tmp_path / "other", phantom_files["femoral"], phantom_files["tibial"],
                                frames=FRAMES, image_size=SIZE, seed=6, start_frame=START)
    assert load_project(again).settings["truth"] == truth
    image = "cam1/frame_0008.png"
    assert (built.parent / image).read_bytes() == (again.parent / image).read_bytes()
    assert (built.parent / image).read_bytes() != (other.parent / image).read_bytes()
    assert load_project(other).settings["truth"] == truth  # the seed changes noise, not the motion


def test_true_outlines_lie_on_the_dark_metal_edges(built, phantom_files):
    project = load_project(built)
    meshes = {c: load_mesh(p) for c, p in phantom_files.items()}
    for i, frame in enumerate(project.frames):
        truth = {c: np.array(p) for c, p in project.settings["truth"][str(frame)].items()}
        for view, sequence in zip(project.views, project.sequences):
            image = read_image(sequence.paths[i])
            for component, mesh in meshes.items():
                inside = image[ring(filled_mask(view, truth[component], mesh), 1, 3, False)].mean()
                assert inside < 0.35, (frame, view.name, component, inside)
            contrast = edge_contrast(image, view, truth, meshes)
            assert contrast > 0.2, (frame, view.name, contrast)
            # each outline is sharpest at the true pose: shifted by 1.5 mm across the beam
            # (along the image rows or columns) it lies partly on the metal, partly beside it
            for component, mesh in meshes.items():
                other = next(c for c in meshes if c != component)
                elsewhere = filled_mask(view, truth[other], meshes[other])
                sharp = own_edge_contrast(image, view, truth[component], mesh, elsewhere)
                assert sharp > 0.25, (frame, view.name, component, sharp)
                for direction in (view.e_u, -view.e_u, view.e_v, -view.e_v):
                    moved = truth[component] + np.concatenate([1.5 * direction, np.zeros(3)])
                    blurred = own_edge_contrast(image, view, moved, mesh, elsewhere)
                    assert blurred < sharp - 0.005, (frame, view.name, component, direction, sharp, blurred)


def test_components_overlap_in_the_lateral_view_and_stay_in_the_field(built, phantom_files):
    project = load_project(built)
    meshes = {c: load_mesh(p) for c, p in phantom_files.items()}
    recipe = project.settings["synthetic"]
    lateral = next(v for v in project.views if v.name == recipe["overlap_view"])
    radius = FIELD_RADIUS_FRACTION * SIZE
    overlaps = []
    for frame in project.frames:
        truth = project.settings["truth"][str(frame)]
        masks = {c: filled_mask(lateral, truth[c], m) for c, m in meshes.items()}
        overlaps.append(int((masks["femoral"] & masks["tibial"]).sum()))
        for view in project.views:
            for component, (vertices, _) in meshes.items():
                uv = pinhole(view, posed(truth[component], vertices))
                reach = np.linalg.norm(uv - (SIZE - 1) / 2.0, axis=1).max()
                assert reach < radius - 5, (frame, view.name, component)
        # femur above tibia in both images (rows grow downwards)
        for view in project.views:
            rows = {c: pinhole(view, posed(truth[c], m[0]))[:, 1].mean() for c, m in meshes.items()}
            assert rows["femoral"] < rows["tibial"]
    assert min(overlaps) > 5, overlaps  # pixels at 256 x 256
    assert all(n > 0 for n in recipe["overlap_px"][lateral.name])
    assert min(recipe["field_margin_px"].values()) > 5


def test_left_knee_mirrors_the_motion_and_the_views(phantom_files):
    meshes = {c: load_mesh(p) for c, p in phantom_files.items()}
    flexion = flexion_schedule(5)
    right = knee_bend_truth(meshes["femoral"][0], meshes["tibial"][0], flexion, "right")
    left = knee_bend_truth(meshes["femoral"][0], meshes["tibial"][0], flexion, "left")
    mirror = np.diag([-1.0, 1.0, 1.0])
    for r, lt in zip(right, left):
        R, L = pose_to_matrix(r["tibial"]), pose_to_matrix(lt["tibial"])
        np.testing.assert_allclose(L[:3, :3], mirror @ R[:3, :3] @ mirror, atol=1e-12)
        np.testing.assert_allclose(L[:3, 3], mirror @ R[:3, 3], atol=1e-12)
        rel_r = np.linalg.inv(R) @ pose_to_matrix(r["femoral"])
        rel_l = np.linalg.inv(L) @ pose_to_matrix(lt["femoral"])
        np.testing.assert_allclose(rel_l[:3, :3], mirror @ rel_r[:3, :3] @ mirror, atol=1e-12)
    for a, b in zip(synthetic.sequence_views(SIZE, "right"), synthetic.sequence_views(SIZE, "left")):
        np.testing.assert_allclose(b.source, mirror @ a.source, atol=1e-9)


# -- the motion ---------------------------------------------------------------------------------
def test_knee_bends_from_extension_to_100_degrees_with_varying_speed():
    flexion = flexion_schedule(100)
    steps = np.diff(flexion)
    assert flexion[0] == pytest.approx(0.0) and flexion[-1] == pytest.approx(100.0)
    assert np.all(steps >= 0)
    assert 3.0 <= steps.max() <= 4.0 and steps.min() < 0.05
    slow = steps < 0.25 * steps.max()
    assert slow[:3].all() and slow[-3:].all() and slow[45:50].all()  # slow ends and a near pause
    assert flexion_schedule(1).tolist() == [0.0]


def test_femur_rests_on_the_insert_gap_and_flexes_about_the_mediolateral_axis(phantom_files):
    meshes = {c: load_mesh(p) for c, p in phantom_files.items()}
    flexion = flexion_schedule(12)
    truth = knee_bend_truth(meshes["femoral"][0], meshes["tibial"][0], flexion)
    tray_top = meshes["tibial"][0][:, 2].max()
    for angle, poses in zip(flexion, truth):
        relative = np.linalg.inv(pose_to_matrix(poses["tibial"])) @ pose_to_matrix(poses["femoral"])
        in_tibia = meshes["femoral"][0] @ relative[:3, :3].T + relative[:3, 3]
        assert in_tibia[:, 2].min() - tray_top == pytest.approx(synthetic.GAP_MM, abs=1e-9)
        # the femoral mediolateral axis stays within a few degrees of the tibial one
        assert np.degrees(np.arccos(relative[0, 0])) < 12.0  # measured 1.6 (extended) to 10.0 (100 deg)
        # flexion: the femoral long axis turned backwards by about the flexion angle
        long_axis = relative[:3, 2]
        turned = np.degrees(np.arctan2(-long_axis[1], long_axis[2]))
        assert turned == pytest.approx(angle, abs=0.39)  # measured within 0.196 deg
        assert relative[1, 3] <= 1.0 + 1e-9  # no forward slide; rollback increases with flexion


# -- the fast rasteriser ----------------------------------------------------------------------
def _check_same_as_plain_rasteriser(mesh, poses, views):
    vertices, faces = mesh
    topology = MeshTopology.of(vertices, faces)
    for pose in poses:
        world = posed(pose, vertices)
        for view in views:
            fast = metal_coverage(view, world, faces, topology)
            plain = coverage_of_meshes(view, [(world, faces)], 8)
            assert plain.sum() > 100
            np.testing.assert_array_equal(fast, plain)


def test_fast_coverage_equals_the_plain_rasteriser_on_closed_open_and_inverted_meshes():
    views = synthetic.sequence_views(384)
    vertices, faces = femoral_component_mesh()
    poses = [np.array([3.0, -2.0, 20.0, a, 4.0, -6.0]) for a in (0.0, 50.0, 95.0)]
    _check_same_as_plain_rasteriser((vertices, faces), poses, views)
    _check_same_as_plain_rasteriser((vertices, faces[:, ::-1]), poses[:1], views)  # faces turned inwards
    open_mesh = (vertices, np.delete(faces, [10, 11, 500, 2000], axis=0))  # four holes
    assert len(MeshTopology.of(*open_mesh).holes) >= 1
    _check_same_as_plain_rasteriser(open_mesh, poses, views)
    mixed = faces.copy()
    mixed[:50] = mixed[:50, ::-1]
    assert MeshTopology.of(vertices, mixed).orientation == 0  # inconsistent: rendered the plain way
    _check_same_as_plain_rasteriser((vertices, mixed), poses[:1], views)


@pytest.mark.slow
def test_worker_processes_write_the_same_sequence(phantom_files, tmp_path):
    one = build_knee_sequence(tmp_path / "one", phantom_files["femoral"], phantom_files["tibial"], frames=3,
                              image_size=96, seed=2)
    two = build_knee_sequence(tmp_path / "two", phantom_files["femoral"], phantom_files["tibial"], frames=3,
                              image_size=96, seed=2, workers=2)
    for folder in ("cam1", "cam2"):
        for image in sorted((one.parent / folder).iterdir()):
            assert image.read_bytes() == (two.parent / folder / image.name).read_bytes()
    assert load_project(one).settings == load_project(two).settings


def test_sixteen_bit_images(phantom_files, tmp_path):
    path = build_knee_sequence(tmp_path, phantom_files["femoral"], phantom_files["tibial"], frames=1,
                               image_size=96, bits=16)
    pixels = cv2.imread(str(path.parent / "cam2" / "frame_0000.png"), cv2.IMREAD_UNCHANGED)
    assert pixels.dtype == np.uint16 and pixels.shape == (96, 96)
    with pytest.raises(ValueError):
        build_knee_sequence(tmp_path / "x", phantom_files["femoral"], phantom_files["tibial"], side="middle")


# -- the real implant meshes ------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.skipif(not REAL_MODELS.is_dir(), reason="../shared/data is not available")
def test_real_meshes_bend_overlapping_in_the_lateral_view(tmp_path):
    femoral, tibial = REAL_MODELS / "femoral_component.stl", REAL_MODELS / "tibial_component.stl"
    path = build_knee_sequence(tmp_path, femoral, tibial, frames=2)  # extension and 100 deg of flexion
    project = load_project(path)
    assert {m.component: m.mesh_path for m in project.models} == {"femoral": femoral, "tibial": tibial}
    recipe = project.settings["synthetic"]
    assert min(recipe["overlap_px"]["cam1"]) > 500  # 1024 x 1024 pixels
    assert min(recipe["field_margin_px"].values()) > 50
    meshes = {"femoral": load_mesh(femoral), "tibial": load_mesh(tibial)}
    for i, frame in enumerate(project.frames):
        truth = {c: np.array(p) for c, p in project.settings["truth"][str(frame)].items()}
        relative = np.linalg.inv(pose_to_matrix(truth["tibial"])) @ pose_to_matrix(truth["femoral"])
        long_axis = relative[:3, 2]  # the femoral long axis, turned backwards by the flexion
        turned = np.degrees(np.arctan2(-long_axis[1], long_axis[2]))
        assert turned == pytest.approx(recipe["flexion_deg"][i], abs=0.3)  # measured -0.013, +0.148 deg
        for view, sequence in zip(project.views, project.sequences):
            image = read_image(sequence.paths[i])
            assert edge_contrast(image, view, truth, meshes) > 0.2
    # the fast rasteriser is exact on the real meshes too (the femoral one has a hole)
    last = project.settings["truth"][str(project.frames[-1])]
    for component, mesh in meshes.items():
        _check_same_as_plain_rasteriser(mesh, [np.array(last[component])], project.views[:1])
