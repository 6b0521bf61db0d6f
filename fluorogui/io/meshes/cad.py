"""Implant models as manufacturers ship them: STEP and IGES surfaces (NURBS and the like),
meshed into triangles at a chosen chordal tolerance.

gmsh (its OpenCASCADE kernel) reads the file and triangulates every face with
OpenCASCADE's mesher (``BRepMesh``): no point of a triangle is farther than
``tolerance_mm`` from the true surface (the linear deflection, checked by measuring and
met by meshing again finer where OpenCASCADE strays) and neighbouring normals turn by at
most ``ANGULAR_DEFLECTION_RAD``; the vertices lie on the surface. The faces of a solid are
meshed to shared edge points, so the triangles join into one closed surface, wound
outwards (faces whose shared edges were meshed apart, as in some IGES files, leave seams
open, which are counted). Lengths are converted to millimetres from the file's own unit.

gmsh is the optional ``cad`` extra (``pip install 'fluorogui[cad]'``): its wheel is some
90 MB with OpenCASCADE inside, and on Linux it needs the system's libGLU, libXft and
libXinerama. Without it a STEP or IGES model is refused with a message saying so. It was
chosen over OpenCASCADE's own bindings (cadquery-ocp 8.0.1), which mesh alike (a filleted
block: 51,000 triangles in 0.6 s either way) but took 1.0-1.7 s to import and a peak of
265 MB against gmsh's 0.2-0.3 s and 41 MB (Python alone: 8 MB), install 440 MB against 89,
and pin VTK 9.6.2 where fluorogui runs on 9.7.
"""
from __future__ import annotations

import os
import sys
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fluorogui.io.errors import InputError

CAD_SUFFIXES = (".step", ".stp", ".iges", ".igs")
#: the default chordal tolerance (mm): the real biplane femoral model's facets (0.43 mm
#: median edge on ~20 mm condyle radii) deviate some 0.001-0.007 mm from their surface, and the
#: matcher's accuracy is some 0.02 mm; 0.02 mm keeps a femoral component near 10^5 triangles
DEFAULT_TOLERANCE_MM = 0.02
TOLERANCE_RANGE_MM = (0.001, 1.0)
ANGULAR_DEFLECTION_RAD = 0.5
_LOCK = threading.Lock()  # gmsh is one global state per process
MISSING = ("reading STEP and IGES models needs gmsh: pip install 'fluorogui[cad]' (on Linux also the system "
           "libraries libglu1-mesa, libxft2 and libxinerama1)")


def is_cad(path) -> bool:
    return Path(path).suffix.lower() in CAD_SUFFIXES


def check_tolerance(tolerance_mm) -> float:
    """A chordal tolerance within ``TOLERANCE_RANGE_MM`` or ValueError."""
    low, high = TOLERANCE_RANGE_MM
    try:
        value = float(tolerance_mm)
    except (TypeError, ValueError):
        raise ValueError(f"the meshing tolerance must be a number of mm, not {tolerance_mm!r}") from None
    if not (np.isfinite(value) and low <= value <= high):
        raise ValueError(f"the meshing tolerance must be {low:g} to {high:g} mm, not {tolerance_mm!r}")
    return value


def _sniff(path: Path) -> None:
    """Refuse, before OpenCASCADE sees it, a file that is not STEP or IGES text."""
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if not head.strip():
        raise InputError(path, "file is empty")
    if path.suffix.lower() in (".step", ".stp"):
        if b"ISO-10303-21" not in head[:1024]:
            raise InputError(path, "not a STEP file (no 'ISO-10303-21' header)")
    else:
        first = head.split(b"\n", 1)[0].rstrip(b"\r")
        if len(first) < 73 or first[72:73] not in b"SGFB":  # IGES: 80-column records, section letter in column 73
            raise InputError(path, "not an IGES file (its records are not 80 columns with a section letter)")


@contextmanager
def _quiet_stdout():
    """OpenCASCADE prints translation statistics on the process's stdout (fd 1), where a
    command's JSON goes: send them to the null device while gmsh reads."""
    try:
        sys.stdout.flush()
        saved = os.dup(1)
        null = os.open(os.devnull, os.O_WRONLY)
    except (OSError, ValueError, AttributeError):
        yield
        return
    try:
        os.dup2(null, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)


def _gmsh():
    try:
        import gmsh
    except (ImportError, OSError):  # OSError: the wheel's library misses a system library
        return None
    return gmsh


def cad_available() -> bool:
    """Whether STEP and IGES models can be read here."""
    return _gmsh() is not None


@dataclass(frozen=True)
class CadMesh:
    """A meshed STEP or IGES model: vertices (mm), triangles, the chordal tolerance asked
    for, the deflection OpenCASCADE was given to meet it, the largest distance measured
    from the triangles (their centroids and edge midpoints) to the true surfaces, and the
    edges left open (seams where two faces were meshed with different points)."""

    vertices: np.ndarray
    faces: np.ndarray
    tolerance_mm: float
    deflection_mm: float
    deviation_mm: float
    open_edges: int

    def describe(self) -> str:
        seams = f"; {self.open_edges:,} edges open along seams between faces" if self.open_edges else ""
        return (f"meshed within {self.tolerance_mm:g} mm of its surfaces: {len(self.faces):,} triangles, "
                f"{self.deviation_mm:.3g} mm at most from the surfaces (measured at their centroids and "
                f"edge midpoints){seams}")


def mesh_cad(path, tolerance_mm: float = DEFAULT_TOLERANCE_MM) -> CadMesh:
    """A STEP or IGES model meshed within ``tolerance_mm`` of its surfaces.

    OpenCASCADE's deflection is not a strict bound (near a sphere's poles its triangles
    stray twice as far), so the distance from each triangle's centroid and edge midpoints
    to its surface is measured (``gmsh.model.getClosestPoint``) and, while it exceeds the
    tolerance, the model is meshed again with a proportionally smaller deflection (while
    that helps). The deviation left is stated (``CadMesh.describe``); beyond
    ``REFUSED_DEVIATION`` tolerances the meshing failed and the model is refused.

    Raises
    ------
    InputError
        gmsh is missing, the file is not STEP or IGES, holds no surface, cannot be read,
        or cannot be meshed near its surfaces.
    """
    path = Path(path)
    tolerance = check_tolerance(tolerance_mm)
    _sniff(path)
    gmsh = _gmsh()
    if gmsh is None:
        raise InputError(path, MISSING)
    deflection = tolerance
    with _LOCK, _quiet_stdout():
        ours = not gmsh.isInitialized()
        if ours:
            gmsh.initialize(["-noenv"], readConfigFiles=False, interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.option.setNumber("Geometry.OCCSewFaces", 1)  # IGES surfaces come unsewn
            gmsh.option.setString("Geometry.OCCTargetUnit", "MM")  # from the file's own unit
            vertices, faces, deviation = _mesh_once(gmsh, path, deflection)
            for _ in range(REMESHES):  # finer while it helps, within the triangles a model may have
                finer = deflection * 0.8 * tolerance / deviation
                if deviation <= tolerance or finer < tolerance / 8 or len(faces) * deflection / finer > MAX_TRIANGLES:
                    break
                again = _mesh_once(gmsh, path, finer)
                if again[2] > 0.8 * deviation:  # not a matter of size (a damaged face?): keep the coarser
                    break
                (vertices, faces, deviation), deflection = again, finer
        finally:
            if ours:
                gmsh.finalize()
    if deviation > REFUSED_DEVIATION * tolerance:
        raise InputError(path, f"OpenCASCADE could not mesh the {_kind(path)} surfaces within {tolerance:g} mm: "
                               f"some triangles lie {deviation:.3g} mm from their surface (a damaged or badly trimmed "
                               "face?); repair the model, or export it as STL from the CAD program")
    faces = outward(vertices, faces)
    sorted_edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(sorted_edges, axis=0, return_counts=True)
    return CadMesh(vertices, faces, tolerance, deflection, deviation, int(np.count_nonzero(counts != 2)))


#: how many times a model is meshed again when its triangles stray beyond the tolerance
REMESHES = 3
#: a model is not meshed again into more triangles than this (``headers.MAX_SIMPLIFIED_FACES``)
MAX_TRIANGLES = 1_000_000
#: triangles this many tolerances from their surface are a failed meshing, refused
REFUSED_DEVIATION = 10.0


def _mesh_once(gmsh, path: Path, deflection: float) -> tuple[np.ndarray, np.ndarray, float]:
    """One meshing at ``deflection``: vertices, triangles and the largest deviation measured."""
    gmsh.model.add("fluorogui-cad")
    try:
        gmsh.option.setNumber("Mesh.StlLinearDeflection", deflection)
        gmsh.option.setNumber("Mesh.StlLinearDeflectionRelative", 0)
        gmsh.option.setNumber("Mesh.StlAngularDeflection", ANGULAR_DEFLECTION_RAD)
        try:
            gmsh.model.occ.importShapes(str(path))
            gmsh.model.occ.synchronize()
        except Exception as exc:  # noqa: BLE001 - gmsh raises plain Exception with its last error
            reason = " ".join(str(exc).split())[:160] or "OpenCASCADE could not translate it"
            raise InputError(path, f"unreadable {_kind(path)} file: {reason}") from None
        surfaces = gmsh.model.getEntities(2)
        if not surfaces:
            raise InputError(path, f"the {_kind(path)} file holds no surfaces (only points or curves?)")
        gmsh.model.mesh.importStl()
        gmsh.model.mesh.removeDuplicateNodes()
        tags, coords, _ = gmsh.model.mesh.getNodes()
        if len(tags) == 0:
            raise InputError(path, f"OpenCASCADE made no triangles of the {_kind(path)} surfaces")
        lookup = np.zeros(int(tags.max()) + 1, dtype=np.int64)
        lookup[tags.astype(np.int64)] = np.arange(len(tags))
        vertices = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
        faces, deviation = [], 0.0
        for dim, tag in surfaces:
            types, _, connectivity = gmsh.model.mesh.getElements(dim, tag)
            for kind, nodes in zip(types, connectivity):
                if kind != 2 or len(nodes) == 0:  # 2: three-node triangles
                    continue
                triangles = lookup[np.asarray(nodes, dtype=np.int64)].reshape(-1, 3)
                corners = vertices[triangles]
                probes = np.concatenate([corners.mean(axis=1), 0.5 * (corners[:, 0] + corners[:, 1]),
                                         0.5 * (corners[:, 1] + corners[:, 2]), 0.5 * (corners[:, 2] + corners[:, 0])])
                on_surface, _ = gmsh.model.getClosestPoint(dim, tag, probes.ravel())
                distance = np.linalg.norm(np.asarray(on_surface).reshape(-1, 3) - probes, axis=1)
                deviation = max(deviation, float(distance.max()))
                faces.append(triangles)
        if not faces:
            raise InputError(path, f"OpenCASCADE made no triangles of the {_kind(path)} surfaces")
        return vertices, np.concatenate(faces), deviation
    finally:
        gmsh.model.remove()


def _kind(path: Path) -> str:
    return "STEP" if path.suffix.lower() in (".step", ".stp") else "IGES"


def outward(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The non-degenerate triangles, wound so a closed surface's normals point out (the
    faces' own triangulations agree in winding; zero-area slivers at poles do not)."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    cross = np.cross(b - a, c - a)
    area = np.linalg.norm(cross, axis=1)
    keep = area > 1e-12 * max(1.0, float(np.max(area, initial=0.0)))
    faces, a, cross = faces[keep], a[keep], cross[keep]
    if np.einsum("ij,ij->", a, cross) < 0:  # six times the enclosed volume
        faces = faces[:, ::-1].copy()
    return faces
