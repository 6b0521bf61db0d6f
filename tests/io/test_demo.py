"""The generated demo project: complete, loadable, images agree with the stored truth, cached."""
from __future__ import annotations

import os

import cv2
import numpy as np
import pytest

from fluorogui.core.projection.pose import transform_points
from fluorogui.io.calibration import load_view
from fluorogui.io.images import read_image
from fluorogui.io.meshes.read import load_mesh
from fluorogui.io.project.document import load_project
from fluorogui.simulation import demo
from fluorogui.simulation.demo import build_demo_project, demo_project_path
from fluorogui.simulation.phantoms import femoral_component_mesh
from fluorogui.simulation.render import render_silhouette

FRAMES = 4


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    folder = tmp_path_factory.mktemp("demo")
    return build_demo_project(folder, frames=FRAMES)  # its build time: benchmarks/bench_budgets.py


def test_demo_is_a_complete_project(built):
    path = built
    project = load_project(path)
    assert len(project.views) == 2
    assert project.frames == list(range(FRAMES))
    assert [len(s.paths) for s in project.sequences] == [FRAMES, FRAMES]
    assert sorted(m.component for m in project.models) == ["femoral", "tibial"]
    for sequence in project.sequences:
        assert all(p.is_file() and p.is_relative_to(path.parent) for p in sequence.paths)
    for view in project.views:
        assert view.image_size == (1024, 1024)
        assert 1150 <= view.distance <= 1250 and 0.25 <= view.pitch[0] <= 0.35
    # views about 60-70 degrees apart, calibration files written as our JSON
    angle = np.degrees(np.arccos(project.views[0].normal @ project.views[1].normal))
    assert 60.0 <= angle <= 70.0
    for k, view in enumerate(project.views):
        saved = load_view(path.parent / "calibration" / f"cam{k + 1}.json")
        assert saved.to_dict() == view.to_dict()


def test_models_are_the_phantoms_in_mm(built):
    project = load_project(built)
    vertices, faces = load_mesh(project.model("femoral").mesh_path)
    expected, _ = femoral_component_mesh()
    np.testing.assert_allclose(vertices.min(0), expected.min(0), atol=1e-4)
    np.testing.assert_allclose(vertices.max(0), expected.max(0), atol=1e-4)
    for model in project.models:
        vertices, _ = load_mesh(model.mesh_path)
        assert 60.0 < np.linalg.norm(np.ptp(vertices, axis=0)) < 150.0  # implant-sized in mm


def test_truth_and_rough_start_are_stored(built):
    project = load_project(built)
    truth = project.settings["demo_truth"]
    assert sorted(truth, key=int) == [str(f) for f in project.frames]
    flexion = []
    for frame in project.frames:
        poses = truth[str(frame)]
        assert set(poses) == {"femoral", "tibial"} and all(len(p) == 6 for p in poses.values())
        flexion.append(poses["femoral"][3] - poses["tibial"][3])
    assert np.all(np.diff(flexion) > 0)  # the knee bends
    assert set(project.poses) == {(0, "femoral"), (0, "tibial")}
    for (frame, component), record in project.poses.items():
        assert record.match is None
        offset = np.abs(record.pose - np.array(truth[str(frame)][component]))
        assert np.all(offset >= 1.0) and np.all(offset <= 5.0)


def test_images_show_both_components_where_the_truth_projects(built):
    project = load_project(built)
    meshes = {m.component: load_mesh(m.mesh_path) for m in project.models}
    for i, frame in enumerate(project.frames):
        truth = project.settings["demo_truth"][str(frame)]
        for view, sequence in zip(project.views, project.sequences):
            image = read_image(sequence.paths[i])
            assert image.shape == (1024, 1024)
            covers = {}
            for component, (vertices, faces) in meshes.items():
                covers[component] = render_silhouette(view, transform_points(truth[component], vertices), faces, 2)
            union = np.maximum(*covers.values()) > 0
            near = cv2.dilate(union.astype(np.uint8), np.ones((21, 21), np.uint8)) > 0
            touching = cv2.dilate(union.astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
            around = image[near & ~touching].mean()
            for component, cover in covers.items():
                inside = image[cover > 0.999].mean()
                assert inside < 0.4 and inside < around - 0.2, (frame, view.name, component, inside, around)
            # femur above tibia in the image (rows grow downwards)
            rows = {c: np.nonzero(cov > 0.5)[0].mean() for c, cov in covers.items()}
            assert rows["femoral"] < rows["tibial"]


def test_same_seed_same_demo_other_seed_other_images(tmp_path):
    a = build_demo_project(tmp_path / "a", frames=1, image_size=128, seed=3)
    b = build_demo_project(tmp_path / "b", frames=1, image_size=128, seed=3)
    c = build_demo_project(tmp_path / "c", frames=1, image_size=128, seed=4)
    image = "cam1/frame_000.png"
    assert (a.parent / image).read_bytes() == (b.parent / image).read_bytes()
    assert (a.parent / image).read_bytes() != (c.parent / image).read_bytes()
    assert a.read_text() == b.read_text()  # paths are stored relative to the project


def test_cached_demo_is_reused_and_rebuilt_when_the_recipe_changes(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    first = demo_project_path(cache, frames=1, image_size=128)
    assert first.is_file() and load_project(first).frames == [0]
    os.utime(first, ns=(10**18, 10**18))  # a mark a rebuild would not keep
    assert demo_project_path(cache, frames=1, image_size=128) == first
    assert first.stat().st_mtime_ns == 10**18

    monkeypatch.setattr(demo, "RECIPE_VERSION", demo.RECIPE_VERSION + 1)
    again = demo_project_path(cache, frames=1, image_size=128)
    assert again == first and again.stat().st_mtime_ns != 10**18
    assert load_project(again).settings["demo"]["recipe_version"] == demo.RECIPE_VERSION
    assert [p.name for p in cache.iterdir()] == ["demo"]  # no scratch folders left behind


def test_cached_demo_is_rebuilt_when_files_are_missing_or_arguments_differ(tmp_path):
    cache = tmp_path / "cache"
    path = demo_project_path(cache, frames=2, image_size=128)
    (path.parent / "cam2" / "frame_001.png").unlink()
    path = demo_project_path(cache, frames=2, image_size=128)
    assert (path.parent / "cam2" / "frame_001.png").is_file()
    path = demo_project_path(cache, frames=3, image_size=128)
    assert load_project(path).frames == [0, 1, 2]
