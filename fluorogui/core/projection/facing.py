"""Which edges of a mesh lie on its silhouette seen from a point source, kept between calls.

An edge is on the silhouette when one of its two faces faces the source (``n . s >
offset``, model frame) and the other does not. The matcher asks for it at every
evaluation, from sources that move by hundredths of a millimetre between calls, so the
answer is kept per mesh and updated only where it can have changed:

* A *facing reference* at a source ``s_r`` holds the faces whose plane passes within
  ``FACING_MARGIN_MM`` of it, sorted by that distance ``|h_r|``. A face's height above its
  plane changes by at most how far the source moved (unit normals), so from a source
  ``d`` away only the faces with ``|h_r| <= d`` (plus a rounding allowance) can face the
  other way: a prefix of the sorted list, the only faces tested again. A reference serves
  sources up to half the margin away.
* The edges whose state changed are those with exactly one of their two faces turned, so
  the silhouette is the reference's one with those toggled. The same turned faces as the
  call before give the very edge set of that call, with its vertex bookkeeping
  (``EdgeSet``): nothing is recomputed.

The result is what the plain test of every face gives, bit for bit
(``tests/core/test_silhouette_exact.py``). The cached arrays are read-only; state is
replaced, never changed in place, so threads (one per view) may share a mesh.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fluorogui.core.projection.mesh import PreparedMesh, face_edges

#: a facing reference is made with the faces whose plane passes within this distance (mm)
#: of the source, and serves sources up to half of it away
FACING_MARGIN_MM = 40.0
#: facing references kept per mesh (the most recently made first)
FACING_REFERENCES = 8
#: faces this much (relative to the source's distance) closer to grazing than the bound are
#: tested again too: far above the rounding of a height (a few 1e-16 of it)
_ROUNDING = 1e-9


@dataclass(frozen=True)
class EdgeSet:
    """Silhouette edges and what drawing them needs, shared by the calls that see them."""

    edges: np.ndarray  # (S, 2) vertex indices: the silhouette edges in index order, then the open edges
    ends: np.ndarray  # (V,) sorted indices of the vertices they use
    local: np.ndarray  # (S, 2) ``edges`` as indices into ``ends``


def edge_set(mesh: PreparedMesh, on: np.ndarray) -> EdgeSet:
    """The ``EdgeSet`` of the sorted edge indices ``on`` (open edges always added)."""
    edges = np.take(mesh.edges, on, axis=0)  # np.take: several times faster than a boolean mask here
    if len(mesh.open_edges):
        edges = np.vstack([edges, mesh.open_edges])
    used = np.zeros(len(mesh.vertices), dtype=bool)
    used[edges.ravel()] = True
    ends = np.flatnonzero(used)  # (np.unique without a sort)
    remap = np.empty(len(mesh.vertices), dtype=np.int64)
    remap[ends] = np.arange(len(ends))
    out = EdgeSet(edges, ends, remap[edges])
    for a in (out.edges, out.ends, out.local):
        a.flags.writeable = False
    return out


@dataclass(frozen=True)
class _FacingReference:
    source: np.ndarray  # (3,) model frame
    faces: np.ndarray  # (F,) the faces within the margin, nearest to grazing first
    normals: np.ndarray  # (F, 3) theirs, in that order
    offsets: np.ndarray  # (F,)
    clearance: np.ndarray  # (F,) |height| of the source above each plane, ascending
    front: np.ndarray  # (F,) facing the source at ``source``
    on: np.ndarray  # sorted indices of the silhouette edges at ``source``
    latest: list  # one slot: (turned faces, EdgeSet) of the last source served


def facing_edges(mesh: PreparedMesh, s_model: np.ndarray) -> EdgeSet:
    """The silhouette edges of ``mesh`` seen from ``s_model`` (model frame)."""
    references = mesh.cache.get("facing", ())
    for ref in references:
        d = s_model - ref.source
        moved = np.sqrt(d @ d)
        if moved <= 0.5 * FACING_MARGIN_MM:
            return _from_reference(mesh, ref, s_model, moved)
    height = mesh.face_normals @ s_model - mesh.face_offsets  # the source's height above each face's plane
    front = height > 0
    on = np.flatnonzero(front[mesh.edge_faces[:, 0]] != front[mesh.edge_faces[:, 1]])
    out = edge_set(mesh, on)
    near = np.flatnonzero(np.abs(height) <= FACING_MARGIN_MM)
    if len(near) > len(height) // 4:  # a source this close to the mesh: a reference would save little
        return out
    faces = near[np.argsort(np.abs(height[near]), kind="stable")]
    ref = _FacingReference(s_model.copy(), faces, mesh.face_normals[faces], mesh.face_offsets[faces],
                           np.abs(height[faces]), front[faces], on, [(faces[:0], out)])
    mesh.cache["facing"] = (ref,) + tuple(references[: FACING_REFERENCES - 1])  # one assignment: thread-safe
    return out


def _from_reference(mesh: PreparedMesh, ref: _FacingReference, s_model: np.ndarray, moved: float) -> EdgeSet:
    # only faces within ``moved`` of grazing at the reference can face the other way now
    reach = moved + _ROUNDING * (1.0 + np.sqrt(s_model @ s_model))
    n = int(np.searchsorted(ref.clearance, reach, side="right"))
    turned = ref.faces[:n][(ref.normals[:n] @ s_model - ref.offsets[:n] > 0) != ref.front[:n]]
    turned.sort()
    last_turned, last = ref.latest[0]
    if np.array_equal(turned, last_turned):
        return last
    # an edge changes state when exactly one of its faces turned
    touched = face_edges(mesh)[turned].ravel()
    touched, count = np.unique(touched[touched >= 0], return_counts=True)
    out = edge_set(mesh, np.setxor1d(ref.on, touched[count == 1], assume_unique=True))
    ref.latest[0] = (turned, out)  # one assignment: thread-safe
    return out
