"""An implant model file as the workflow uses it: read (vertices in mm, in the component's
local frame, a size an implant can have) and prepared for matching (a closed surface, not a
triangle soup). The one reading of a model for the app, the command line and scripts."""
from __future__ import annotations

import numpy as np

from fluorogui.core.projection.mesh import MeshError, PreparedMesh, check_plausible_mm, prepare_mesh
from fluorogui.io.errors import InputError
from fluorogui.io.meshes.read import load_mesh


def read_model(path, local_frame: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (mm, in the component's local frame) and faces of an implant mesh file: the
    one reading of a model for the app, the command line and scripts. A mesh whose size
    cannot be an implant in millimetres is refused; raises InputError naming the file."""
    vertices, faces = load_mesh(path)
    try:
        check_plausible_mm(vertices)
    except MeshError as exc:
        raise InputError(path, str(exc)) from None
    if local_frame is not None and not np.allclose(local_frame, np.eye(4)):
        vertices = vertices @ local_frame[:3, :3].T + local_frame[:3, 3]
    return vertices, faces


#: a model may have this many edges bordering one triangle (or more than two) before it is
#: taken for a triangle soup: the matcher takes every such edge as a silhouette candidate
#: in every view, which made a 400,000-triangle soup need 15 GB
MAX_OPEN_EDGES = 1000
MAX_OPEN_EDGE_SHARE = 0.05
#: the fewest triangles of a surface that encloses a solid (a tetrahedron)
MIN_TRIANGLES = 4
#: a model whose surface lies (RMS) within this of its centre is too small to see or match
MIN_RADIUS_MM = 0.5


def prepared_model(path, vertices: np.ndarray, faces: np.ndarray) -> PreparedMesh:
    """A model read by ``read_model`` prepared for matching; raises InputError naming ``path``,
    also for a model that is not a closed surface (fewer than ``MIN_TRIANGLES`` triangles, or
    more than ``MAX_OPEN_EDGES`` and ``MAX_OPEN_EDGE_SHARE`` of its edges open: a real
    implant model has a few dozen) or too small to see (``MIN_RADIUS_MM``)."""
    try:
        mesh = prepare_mesh(vertices, faces)
    except MeshError as exc:
        raise InputError(path, str(exc)) from None
    if len(mesh.faces) < MIN_TRIANGLES:
        raise InputError(path, f"mesh has {len(mesh.faces)} triangle{'s' if len(mesh.faces) > 1 else ''} "
                               f"of non-zero area; a surface enclosing a solid needs at least {MIN_TRIANGLES}, and "
                               "an implant model has thousands")
    if mesh.radius < MIN_RADIUS_MM:
        raise InputError(path, f"mesh is too small to see: its surface lies within {mesh.radius:.2g} mm of its centre "
                               f"(at least {MIN_RADIUS_MM:g} mm; an implant's is some 10-40 mm)")
    open_edges, edges = len(mesh.open_edges), len(mesh.open_edges) + len(mesh.edges)
    if open_edges > MAX_OPEN_EDGES and open_edges > MAX_OPEN_EDGE_SHARE * edges:
        raise InputError(path, f"mesh is not a closed surface: {open_edges:,} of its {edges:,} edges border one "
                               "triangle (or more than two); an implant model is closed (is it a triangle soup?)")
    return mesh
