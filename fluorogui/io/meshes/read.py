"""Load implant surface models (STL, PLY, OBJ, VTK, VTP; STEP and IGES meshed by ``cad``) as
triangle arrays in millimetres.

The header is checked first (``headers``: counts the file cannot hold, and models of more
faces than can be simplified within 1.5 GB, are refused before VTK allocates for them). PLY
(plyfile) and legacy VTK (``vtk_legacy``) are parsed with numpy and their face indices
checked, since VTK's readers crash on corrupt ones; the others are read through pyvista.
The mesh is then reduced to its surface, triangulated and cleaned of duplicate points. A
model finer than the matcher needs is simplified, its surface error stated in an
``InputWarning`` (``simplify``). The local coordinate system is the file's own.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from fluorogui.io.errors import InputError, describe_os_error, warn_input
from fluorogui.io.files import check_input_file
from fluorogui.io.meshes import headers
from fluorogui.io.meshes.cad import CAD_SUFFIXES, DEFAULT_TOLERANCE_MM, mesh_cad
from fluorogui.io.meshes.headers import HeaderError, check_mesh_header, check_model_faces
from fluorogui.io.meshes.vtk_legacy import LegacyVtkError, read_legacy_polydata

#: surface meshes (the folder importer looks for these); ``load_mesh`` also reads ``CAD_SUFFIXES``
MESH_SUFFIXES = (".stl", ".ply", ".obj", ".vtk", ".vtp")
MODEL_SUFFIXES = MESH_SUFFIXES + CAD_SUFFIXES
MIN_DIAGONAL_MM = 1.0
MAX_DIAGONAL_MM = 1000.0
MAX_MESH_BYTES = 2_000_000_000


def load_mesh(path, tolerance_mm: float = DEFAULT_TOLERANCE_MM) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (N, 3) float64 in mm and triangles (M, 3) int64 of a surface model file.

    A STEP or IGES model is meshed within ``tolerance_mm`` of its surfaces (``cad``); a
    model of more than ``headers.MAX_MODEL_FACES`` triangles is simplified for matching, with an
    ``InputWarning`` stating the surface error.
    """
    path = check_input_file(path, "mesh file")
    suffix = path.suffix.lower()
    if suffix not in MODEL_SUFFIXES:
        raise InputError(path, f"unsupported mesh type '{suffix or '(none)'}' "
                               "(use STL, PLY, OBJ, VTK, VTP, STEP or IGES)")
    if suffix in CAD_SUFFIXES:
        try:
            size = path.stat().st_size
        except OSError as exc:
            raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
        if size > MAX_MESH_BYTES:
            raise InputError(path, f"model file is too large ({size / 1e6:.0f} MB; "
                                   f"at most {MAX_MESH_BYTES / 1e6:.0f} MB)")
        try:
            meshed = mesh_cad(path, tolerance_mm)
        except ValueError as exc:  # the tolerance
            raise InputError(path, str(exc)) from None
        warn_input(path, meshed.describe())
        _check_size(path, len(meshed.faces))
        return _checked(path, meshed.vertices, meshed.faces)
    try:
        size = path.stat().st_size
        if size == 0:
            raise InputError(path, "file is empty")
        if size > MAX_MESH_BYTES:
            raise InputError(path, f"mesh file is too large ({size / 1e6:.0f} MB; "
                                   f"at most {MAX_MESH_BYTES / 1e6:.0f} MB)")
        faces = check_mesh_header(path)  # before VTK allocates what the header claims
    except HeaderError as exc:
        raise InputError(path, f"unreadable mesh file: {exc}") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    _check_size(path, faces)
    surface = _read_surface(path)
    if surface.n_cells == 0 or surface.n_points == 0:
        raise InputError(path, "mesh has no faces")
    vertices = np.asarray(surface.points, dtype=np.float64)
    if not np.all(np.isfinite(vertices)):
        raise InputError(path, "mesh has NaN or infinite vertex coordinates")
    faces = _triangles(surface)
    if faces.shape[0] == 0:
        raise InputError(path, "mesh has no faces")
    _check_size(path, len(faces))  # polygons and strips become more triangles than the header said
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(path, f"a face refers to a vertex beyond the {len(vertices)} the mesh has")
    return _checked(path, vertices, faces)


def _checked(path: Path, vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mesh when its size can be an implant in mm, simplified when finer than the matcher needs."""
    used = np.unique(faces)
    extent = vertices[used].max(axis=0) - vertices[used].min(axis=0)
    diagonal = float(np.linalg.norm(extent))
    if diagonal < MIN_DIAGONAL_MM or diagonal > MAX_DIAGONAL_MM:
        raise InputError(
            path,
            f"implausible size: bounding-box diagonal {diagonal:.4g} (expected {MIN_DIAGONAL_MM:g} to "
            f"{MAX_DIAGONAL_MM:g}); is the mesh in mm?",
        )
    if len(faces) > headers.MAX_MODEL_FACES:
        from fluorogui.io.meshes.simplify import SIMPLIFIED_FACES, simplify

        vertices, faces, report = simplify(vertices, faces, min(SIMPLIFIED_FACES, headers.MAX_MODEL_FACES))
        warn_input(path, report.describe())
    return vertices, faces


def _check_size(path: Path, faces: int) -> None:
    try:
        check_model_faces(faces)
    except HeaderError as exc:
        raise InputError(path, f"mesh too large: {exc}") from None


def _read_ply(path: Path):
    """A PLY file through plyfile (numpy): VTK's PLY reader crashes on face indices out of
    range, so they are checked here before VTK sees the mesh."""
    import pyvista as pv
    from plyfile import PlyData

    try:
        ply = PlyData.read(str(path))
        vertex = ply["vertex"].data
        vertices = np.column_stack([np.asarray(vertex[k], dtype=np.float64) for k in ("x", "y", "z")])
    except (KeyError, ValueError) as exc:
        reason = " ".join(str(exc).split())[:120] or "no x, y, z vertices"
        raise InputError(path, f"unreadable PLY file: {reason}") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    except Exception as exc:  # noqa: BLE001 - plyfile raises several types on corrupt files
        raise InputError(path, f"unreadable PLY file ({type(exc).__name__})") from None
    names = [e.name for e in ply.elements]
    if "face" not in names:
        return pv.PolyData(vertices)
    face = ply["face"].data
    key = next((k for k in ("vertex_indices", "vertex_index") if k in face.dtype.names), None)
    if key is None:
        raise InputError(path, "unreadable PLY file: faces have no vertex_indices")
    polygons = [np.asarray(f, dtype=np.int64) for f in face[key]]
    for polygon in polygons:
        if polygon.size < 3:
            raise InputError(path, "unreadable PLY file: a face has fewer than 3 corners")
        if polygon.min() < 0 or polygon.max() >= len(vertices):
            raise InputError(path, f"unreadable PLY file: a face refers to a vertex beyond the {len(vertices)} it has")
    return _polydata(pv, vertices, polygons)


def _read_vtk(path: Path):
    """A legacy VTK file through ``vtk_legacy`` (VTK's own reader crashes on corrupt cells)."""
    import pyvista as pv

    try:
        points, polygons = read_legacy_polydata(path.read_bytes())
    except LegacyVtkError as exc:
        raise InputError(path, f"unreadable VTK file: {exc}") from None
    return _polydata(pv, points, polygons)


def _polydata(pv, vertices: np.ndarray, polygons: list):
    """PolyData of checked polygons (lists of vertex indices)."""
    if not polygons:
        return pv.PolyData(vertices)
    sizes = np.array([len(p) for p in polygons], dtype=np.int64)
    indices = np.concatenate(polygons).astype(np.int64)
    return pv.PolyData(vertices, faces=np.insert(indices, np.cumsum(np.r_[0, sizes[:-1]]), sizes))


def _read_surface(path: Path):
    import pyvista as pv

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            suffix = path.suffix.lower()
            data = _read_ply(path) if suffix == ".ply" else _read_vtk(path) if suffix == ".vtk" else pv.read(path)
    except InputError:
        raise
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    except Exception as exc:  # VTK readers fail in many ways on corrupt files
        raise InputError(path, f"unreadable mesh file ({type(exc).__name__})") from None
    if data is None or any("raised an error" in str(w.message) for w in caught):
        raise InputError(path, "unreadable mesh file (the reader reported an error)")
    if isinstance(data, pv.MultiBlock):
        data = data.combine()
    if data.n_points == 0:
        raise InputError(path, "mesh has no faces")
    try:
        surface = data if isinstance(data, pv.PolyData) else data.extract_surface()
        if surface.n_cells == 0:
            return surface
        if not np.all(np.isfinite(np.asarray(surface.points))):
            return surface  # reported by the caller; clean() would drop or merge NaNs
        return surface.triangulate().clean()
    except Exception as exc:
        raise InputError(path, f"unreadable mesh file ({type(exc).__name__})") from None


def _triangles(surface) -> np.ndarray:
    """(M, 3) vertex indices of the triangles of a triangulated PolyData (lines, vertices skipped)."""
    cells = np.asarray(surface.faces, dtype=np.int64)
    if cells.size == 0:
        return np.empty((0, 3), dtype=np.int64)
    if np.all(cells[::4] == 3) and cells.size % 4 == 0:
        return cells.reshape(-1, 4)[:, 1:].copy()
    # mixed sizes should not survive triangulate(); walk them to be safe
    triangles = []
    i = 0
    while i < cells.size:
        n = int(cells[i])
        if n == 3:
            triangles.append(cells[i + 1 : i + 4])
        i += n + 1
    return np.array(triangles, dtype=np.int64).reshape(-1, 3)
