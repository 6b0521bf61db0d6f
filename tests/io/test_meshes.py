"""Mesh loading: formats, triangulation, duplicate points, and the bad-input messages."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import pyvista as pv

from fluorogui.io.errors import InputError
from fluorogui.io.meshes.read import load_mesh

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


def error_of(path):
    with pytest.raises(InputError) as info:
        load_mesh(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message


@pytest.mark.parametrize("suffix", [".stl", ".ply", ".obj", ".vtk", ".vtp"])
def test_formats(tmp_path, suffix):
    sphere = pv.Sphere(radius=20.0, theta_resolution=12, phi_resolution=12)
    path = tmp_path / f"ball{suffix}"
    sphere.save(path)
    vertices, faces = load_mesh(path)
    assert vertices.dtype == np.float64 and vertices.shape[1] == 3
    assert faces.dtype == np.int64 and faces.shape == (sphere.n_cells, 3)
    assert faces.min() >= 0 and faces.max() < len(vertices)
    np.testing.assert_allclose(np.linalg.norm(vertices, axis=1), 20.0, rtol=1e-5)


def test_quads_triangulated_and_duplicates_merged(tmp_path):
    cube = pv.Cube(x_length=30, y_length=20, z_length=10)  # 6 quads, 24 points (split normals)
    path = tmp_path / "cube.stl"  # STL stores every triangle's corners separately
    cube.save(path)
    vertices, faces = load_mesh(path)
    assert vertices.shape == (8, 3)
    assert faces.shape == (12, 3)
    path = tmp_path / "cube.vtp"
    cube.save(path)
    vertices, faces = load_mesh(path)
    assert vertices.shape == (8, 3) and faces.shape == (12, 3)


def test_real_stl():
    path = DATA / "biplane-tka" / "models" / "femoral_component.stl"
    if not path.exists():
        pytest.skip("shared data not available")
    vertices, faces = load_mesh(path)
    assert len(faces) > 1000
    diagonal = np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0))
    assert 50 < diagonal < 200


def test_missing_unsupported_empty(tmp_path):
    assert error_of(tmp_path / "none.stl").endswith("file not found")
    (tmp_path / "model.3ds").write_bytes(b"x")
    assert "unsupported mesh type '.3ds'" in error_of(tmp_path / "model.3ds")
    (tmp_path / "empty.stl").write_bytes(b"")
    assert error_of(tmp_path / "empty.stl").endswith("file is empty")


def test_corrupt_file(tmp_path):
    (tmp_path / "junk.ply").write_bytes(b"\x00\x01 this is no mesh " * 20)
    assert "unreadable mesh file" in error_of(tmp_path / "junk.ply")
    (tmp_path / "junk.stl").write_bytes(b"solid x\nfacet garbage\n" * 5)
    message = error_of(tmp_path / "junk.stl")
    assert "unreadable" in message or "no faces" in message


def test_no_faces(tmp_path):
    cloud = pv.PolyData(np.random.default_rng(0).uniform(0, 50, (30, 3)))
    cloud.save(tmp_path / "cloud.vtp")
    assert error_of(tmp_path / "cloud.vtp").endswith("mesh has no faces")
    line = pv.Line((0, 0, 0), (50, 0, 0))
    line.save(tmp_path / "line.vtp")
    assert error_of(tmp_path / "line.vtp").endswith("mesh has no faces")


def test_nan_coordinates(tmp_path):
    (tmp_path / "nan.stl").write_text(
        "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 10 0 0\nvertex nan 10 0\n"
        "endloop\nendfacet\nendsolid t\n"
    )
    assert "NaN or infinite vertex coordinates" in error_of(tmp_path / "nan.stl")


@pytest.mark.parametrize("radius", [0.1, 2000.0])
def test_implausible_size(tmp_path, radius):
    pv.Sphere(radius=radius).save(tmp_path / "ball.stl")
    assert "is the mesh in mm?" in error_of(tmp_path / "ball.stl")


@pytest.mark.parametrize("suffix, binary", [(".stl", True), (".stl", False), (".ply", True), (".obj", None),
                                            (".vtk", False), (".vtp", None)])
def test_models_of_more_faces_than_can_be_simplified_are_refused_before_reading(tmp_path, monkeypatch, suffix,
                                                                                 binary):
    """The count comes from the header (or a count in the file), before VTK allocates."""
    sphere = pv.Sphere(radius=20.0, theta_resolution=12, phi_resolution=12)  # 240 triangles
    path = tmp_path / f"ball{suffix}"
    sphere.save(path, **({} if binary is None else {"binary": binary}))
    monkeypatch.setattr("fluorogui.io.meshes.headers.MAX_SIMPLIFIED_FACES", 239)
    monkeypatch.setattr("fluorogui.io.meshes.headers.MAX_MODEL_FACES", 100)
    read = []
    monkeypatch.setattr("fluorogui.io.meshes.read._read_surface", lambda p: read.append(p))
    assert error_of(path) == (f"{path}: mesh too large: the model has 240 faces, more than the 239 fluorogui "
                              "simplifies (to 100 or fewer for matching; an implant needs some 10^4 to 10^5, and each "
                              "costs memory): decimate it first")
    assert read == []


def test_a_triangle_soup_is_refused_and_a_real_model_is_not(tmp_path):
    from fluorogui.io.meshes.model import MAX_OPEN_EDGES, prepared_model, read_model

    rng = np.random.default_rng(0)
    triangles = rng.uniform(-30, 30, (MAX_OPEN_EDGES, 3, 3))  # no two share an edge: 3,000 open edges
    soup = pv.PolyData(triangles.reshape(-1, 3), np.c_[np.full(len(triangles), 3),
                                                       np.arange(3 * len(triangles)).reshape(-1, 3)].ravel())
    soup.save(tmp_path / "soup.stl")
    with pytest.raises(InputError) as info:
        prepared_model(tmp_path / "soup.stl", *read_model(tmp_path / "soup.stl"))
    assert str(info.value) == (f"{tmp_path / 'soup.stl'}: mesh is not a closed surface: 3,000 of its 3,000 edges "
                               "border one triangle (or more than two); an implant model is closed (is it a triangle "
                               "soup?)")
    femur = DATA / "biplane-tka" / "models" / "femoral_component.stl"
    if femur.exists():  # 15 open edges of 109,686
        assert len(prepared_model(femur, *read_model(femur)).open_edges) == 15


def test_a_mesh_too_small_to_see_is_refused_naming_it(tmp_path):
    """One 10 mm triangle encloses nothing and its surface lies at its centre: it was taken
    for a component 4.4e-15 px across, blamed on the start pose (issue 44)."""
    from fluorogui.io.meshes.model import prepared_model, read_model

    def refusal(name, vertices, faces):
        pv.PolyData(np.asarray(vertices, float), np.c_[np.full(len(faces), 3), faces].ravel()).save(tmp_path / name)
        with pytest.raises(InputError) as info:
            prepared_model(tmp_path / name, *read_model(tmp_path / name))
        return str(info.value)

    assert refusal("one.stl", [[0, 0, 0], [10, 0, 0], [0, 10, 0]], [[0, 1, 2]]) == (
        f"{tmp_path / 'one.stl'}: mesh has 1 triangle of non-zero area; a surface enclosing a solid needs at least 4, "
        "and an implant model has thousands")
    # the same triangle four times over, front and back: its surface lies at its centre
    message = refusal("flat.stl", [[0, 0, 0], [10, 0, 0], [0, 10, 0]], [[0, 1, 2], [0, 2, 1], [0, 1, 2], [0, 2, 1]])
    assert message.startswith(f"{tmp_path / 'flat.stl'}: mesh is too small to see: its surface lies within ")
    ball = pv.Sphere(radius=0.6, theta_resolution=8, phi_resolution=8)  # 1.2 mm across: small, still seen
    ball.save(tmp_path / "bead.stl")
    assert prepared_model(tmp_path / "bead.stl", *read_model(tmp_path / "bead.stl")).radius > 0.5
