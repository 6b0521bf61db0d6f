"""Implant models as manufacturers ship them: STEP and IGES shapes of known dimensions,
made here with the same library (gmsh's OpenCASCADE), meshed within the chosen tolerance
of their true surfaces; and models finer than the matcher needs, simplified with their
surface error stated."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import pyvista as pv

from fluorogui.io.errors import InputError, InputWarning
from fluorogui.io.meshes.read import load_mesh

RADIUS, CYLINDER_RADIUS, CYLINDER_LENGTH = 20.0, 12.0, 30.0


def make_cad(path, shape: str, scale: float = 1.0) -> None:
    """A sphere (radius 20 mm, at the origin) or a cylinder (radius 12 mm, 30 mm along z from
    the origin) written by gmsh as STEP or IGES (by the suffix)."""
    gmsh = pytest.importorskip("gmsh")
    gmsh.initialize(["-noenv"], readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("shape")
        if shape == "sphere":
            gmsh.model.occ.addSphere(0, 0, 0, RADIUS * scale)
        else:
            gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, CYLINDER_LENGTH * scale, CYLINDER_RADIUS * scale)
        gmsh.model.occ.synchronize()
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def read(path, **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        vertices, faces = load_mesh(path, **kwargs)
    return vertices, faces, [str(w.message) for w in caught if issubclass(w.category, InputWarning)]


def sphere_error(points):
    return np.abs(np.linalg.norm(points, axis=1) - RADIUS)


def cylinder_error(points):
    """Distance to the closed cylinder's surface (side wall and the two caps)."""
    rho, z = np.hypot(points[:, 0], points[:, 1]), points[:, 2]
    side = np.where((z >= 0) & (z <= CYLINDER_LENGTH), np.abs(rho - CYLINDER_RADIUS), np.inf)
    caps = np.minimum(np.abs(z), np.abs(z - CYLINDER_LENGTH))
    caps = np.where(rho <= CYLINDER_RADIUS, caps, np.inf)
    return np.minimum(side, caps)


def probes(vertices, faces):
    """Each triangle's centroid and edge midpoints: where a flat triangle strays most."""
    c = vertices[faces]
    return np.concatenate([c.mean(axis=1), (c[:, 0] + c[:, 1]) / 2, (c[:, 1] + c[:, 2]) / 2, (c[:, 2] + c[:, 0]) / 2])


@pytest.mark.parametrize("suffix", [".step", ".igs"])
@pytest.mark.parametrize("tolerance", [0.1, 0.02])
def test_a_step_or_iges_sphere_is_meshed_within_the_tolerance(tmp_path, suffix, tolerance):
    path = tmp_path / f"ball{suffix}"
    make_cad(path, "sphere")
    vertices, faces, notes = read(path, tolerance_mm=tolerance)
    assert sphere_error(vertices).max() < 1e-9  # the vertices lie on the true surface (measured 7e-15)
    # and the triangles within the tolerance: measured 0.074 and 0.016 mm (STEP), 0.096 and 0.017 (IGES)
    assert sphere_error(probes(vertices, faces)).max() <= tolerance
    assert len(notes) == 1 and f"meshed within {tolerance:g} mm of its surfaces" in notes[0]
    # closed, wound outwards: the enclosed volume is the sphere's, less the facets' sagitta
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    volume = np.einsum("ij,ij->", a, np.cross(b, c)) / 6
    assert 0.99 < volume / (4 / 3 * np.pi * RADIUS ** 3) < 1.0


def test_a_step_cylinder_keeps_its_dimensions_and_finer_tolerances_give_more_triangles(tmp_path):
    path = tmp_path / "peg.stp"
    make_cad(path, "cylinder")
    coarse, coarse_faces, _ = read(path, tolerance_mm=0.1)
    fine, fine_faces, _ = read(path, tolerance_mm=0.01)
    for vertices, faces, tolerance in ((coarse, coarse_faces, 0.1), (fine, fine_faces, 0.01)):
        # the box of a polygon inscribed in the circle: within the tolerance (its sagitta) inside
        box = np.array([[-CYLINDER_RADIUS, -CYLINDER_RADIUS, 0], [CYLINDER_RADIUS, CYLINDER_RADIUS, CYLINDER_LENGTH]])
        inset = np.abs(np.array([vertices.min(axis=0), vertices.max(axis=0)]) - box)
        assert inset[:, 2].max() < 1e-6 and inset.max() <= tolerance
        assert np.hypot(vertices[:, 0], vertices[:, 1]).max() == pytest.approx(CYLINDER_RADIUS, abs=1e-6)
        assert cylinder_error(vertices).max() < 1e-9
        assert cylinder_error(probes(vertices, faces)).max() <= tolerance
    assert len(fine_faces) > 2 * len(coarse_faces)


def test_a_step_file_in_metres_is_read_in_millimetres(tmp_path):
    path = tmp_path / "ball.step"
    make_cad(path, "sphere", scale=0.001)  # written as 0.02 mm ...
    text = path.read_text()
    assert "SI_UNIT(.MILLI.,.METRE.)" in text
    path.write_text(text.replace("SI_UNIT(.MILLI.,.METRE.)", "SI_UNIT($,.METRE.)"))  # ... then said to be metres
    vertices, faces, _ = read(path)
    assert sphere_error(vertices).max() < 1e-5  # 0.02 m: 20 mm


def test_cad_files_that_cannot_be_read_get_one_message(tmp_path, monkeypatch):
    bad = tmp_path / "part.step"
    bad.write_text("solid not a step file\n")
    with pytest.raises(InputError, match=r"part.step: not a STEP file \(no 'ISO-10303-21' header\)"):
        load_mesh(bad)
    bad = tmp_path / "part.iges"
    bad.write_text("hello\n")
    with pytest.raises(InputError, match="not an IGES file"):
        load_mesh(bad)
    good = tmp_path / "ball.step"
    make_cad(good, "sphere")
    with pytest.raises(InputError, match="meshing tolerance must be 0.001 to 1 mm"):
        load_mesh(good, tolerance_mm=5)
    truncated = tmp_path / "cut.step"
    truncated.write_text(good.read_text()[: len(good.read_text()) // 2])
    with pytest.raises(InputError, match=r"cut.step: (unreadable STEP file|the STEP file holds no surfaces)"):
        load_mesh(truncated)
    monkeypatch.setattr("fluorogui.io.meshes.cad._gmsh", lambda: None)
    with pytest.raises(InputError, match=r"reading STEP and IGES models needs gmsh: pip install 'fluorogui\[cad\]'"):
        load_mesh(good)


def test_a_model_finer_than_the_matcher_needs_is_simplified_with_its_surface_error(tmp_path, monkeypatch):
    ball = pv.Sphere(radius=RADIUS, theta_resolution=200, phi_resolution=200)  # 79,200 triangles
    path = tmp_path / "fine.stl"
    ball.save(path)
    monkeypatch.setattr("fluorogui.io.meshes.headers.MAX_MODEL_FACES", 20_000)
    vertices, faces, notes = read(path)
    assert 19_000 <= len(faces) <= 20_000
    assert len(notes) == 1
    stated = float(notes[0].split("surface error ")[1].split(" mm")[0])
    assert "simplified from 79,200 to" in notes[0] and "fast-simplification" in notes[0]
    # the simplified vertices stay within the stated error of the original surface, whose
    # facets are within 0.0031 mm of the sphere: measured 0.0048 mm from the sphere
    assert sphere_error(vertices).max() <= stated + 0.0031
    assert 0.001 < stated < 0.015  # measured 0.0071 mm
