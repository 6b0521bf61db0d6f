"""Mesh headers are checked before VTK allocates: counts a file cannot hold are refused."""
from __future__ import annotations

import struct
from pathlib import Path

import pytest
import pyvista as pv

from fluorogui.io.errors import InputError
from fluorogui.io.meshes.read import load_mesh

CORPUS = Path(__file__).resolve().parents[1] / "fuzz" / "corpus"


def refusal(path) -> str:
    with pytest.raises(InputError) as info:
        load_mesh(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message[len(str(path)) + 2:]


def test_tiny_ply_claiming_billions_of_vertices():
    path = CORPUS / "billions.ply"
    assert path.stat().st_size == 278
    assert refusal(path) == ("unreadable mesh file: the header claims 4,000,000,000 vertex elements "
                             "(at most 20,000,000 are read)")


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_ply_claiming_more_than_it_holds(tmp_path, fmt):
    path = tmp_path / "short.ply"
    path.write_bytes(f"ply\nformat {fmt} 1.0\nelement vertex 1000000\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                     "0 0 0\n".encode())
    assert refusal(path) == ("unreadable mesh file: the header claims more elements than the file holds "
                             "(truncated or corrupt)")


def test_binary_stl_count_beyond_its_size(tmp_path):
    path = tmp_path / "short.stl"
    path.write_bytes(b"\0" * 80 + struct.pack("<I", 10_000_000) + b"\0" * 100)
    assert refusal(path) == ("unreadable mesh file: the header claims 10,000,000 triangles but the file is too "
                             "small to hold them (truncated or corrupt)")


def test_legacy_vtk_and_vtp_counts(tmp_path):
    path = tmp_path / "big.vtk"
    path.write_text("# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 900000000 float\n0 0 0\n")
    assert refusal(path) == "unreadable mesh file: the header claims 900,000,000 points (at most 20,000,000 are read)"
    path.write_text("# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 5000 float\n0 0 0\n")
    assert "claims 5,000 points but the file is too small" in refusal(path)
    path = tmp_path / "big.vtp"
    path.write_text('<VTKFile type="PolyData"><PolyData><Piece NumberOfPoints="99999999999" NumberOfPolys="1">')
    assert "claims 99,999,999,999 points" in refusal(path)


@pytest.mark.parametrize("suffix", [".stl", ".ply", ".vtk", ".vtp"])
def test_real_files_pass_the_check(tmp_path, suffix):
    for binary in (True, False):
        path = tmp_path / f"ball{binary}{suffix}"
        sphere = pv.Sphere(radius=20.0)
        if suffix == ".vtp":
            sphere.save(path)
        else:
            sphere.save(path, binary=binary)
        vertices, faces = load_mesh(path)
        assert len(faces) == sphere.n_cells


LEGACY_42 = """# vtk DataFile Version 4.2
tetrahedron
ASCII
DATASET POLYDATA
POINTS 4 float
0 0 0 30 0 0 0 30 0 0 0 30
POLYGONS 4 16
3 0 1 2
3 0 1 3
3 0 2 3
3 1 2 {last}
"""


def test_legacy_vtk_42_is_read_and_its_indices_checked(tmp_path):
    path = tmp_path / "tet.vtk"
    path.write_text(LEGACY_42.format(last=3))
    vertices, faces = load_mesh(path)
    assert vertices.shape == (4, 3) and faces.shape == (4, 3)
    path.write_text(LEGACY_42.format(last=77))
    assert refusal(path) == "unreadable VTK file: a polygon refers to a point beyond the 4 the file has"
    path.write_text(LEGACY_42.format(last=3).replace("POLYGONS 4 16", "POLYGONS 5 16"))
    assert refusal(path) == "unreadable VTK file: the cell list of 'POLYGONS' is inconsistent with its counts"


def test_ply_with_a_face_beyond_its_vertices(tmp_path):
    path = tmp_path / "bad.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0 0\n30 0 0\n0 30 0\n3 0 1 9\n")
    assert refusal(path) == "unreadable PLY file: a face refers to a vertex beyond the 3 it has"
