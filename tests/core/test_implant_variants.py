"""Procedural implant variants (``simulation.implant_variants`` via ``simulation.protocols.mesh_variant``):
closed meshes, shaped as their names say."""
import numpy as np
import pytest
from scipy.spatial import cKDTree

from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.silhouette import mesh_silhouette
from fluorogui.simulation.implant_variants import box_mesh, ps_box_bounds
from fluorogui.simulation.phantoms import femoral_component_mesh, signed_volume, tibial_component_mesh
from fluorogui.simulation.protocols import mesh_variant


def _edge_use(faces) -> np.ndarray:
    """How many faces share each undirected edge."""
    f = np.asarray(faces)
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    return np.unique(edges, axis=0, return_counts=True)[1]


def _directed_edges_unique(faces) -> bool:
    """Consistent orientation: no directed edge appears twice."""
    f = np.asarray(faces)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    return len(np.unique(directed, axis=0)) == len(directed)


def _lateral_area(vertices, faces) -> float:
    """Area (px) of the silhouette seen along the mediolateral axis."""
    view = View.looking_at([-1000, 0, 0], [0, 0, 0], [0, 0, 1], 1200, image_size=(1024, 1024), pitch=315 / 1024)
    p = mesh_silhouette(prepare_mesh(vertices, faces), np.eye(3), np.zeros(3), view, spacing_px=1.0).points_px
    return 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))


def test_box_is_closed_and_faces_outwards():
    v, f = box_mesh([0, 0, 0], [2, 3, 4])
    assert np.all(_edge_use(f) == 2) and _directed_edges_unique(f)
    assert signed_volume(v, f) == pytest.approx(24.0)


def test_ps_box_adds_a_closed_box_between_the_condyles():
    v, f = femoral_component_mesh()
    pv_, pf = mesh_variant(v, f, "ps-box")
    assert np.all(_edge_use(pf) == 2) and _directed_edges_unique(pf)  # still closed, oriented
    lo, hi = ps_box_bounds(v)
    assert signed_volume(pv_, pf) == pytest.approx(signed_volume(v, f) + np.prod(hi - lo))
    width = v[:, 0].max() - v[:, 0].min()
    assert (hi - lo)[0] == pytest.approx(0.2 * width)
    assert abs((hi + lo)[0] / 2 - (v[:, 0].max() + v[:, 0].min()) / 2) < 1e-9
    # the box shows: the outline seen from the side grows (measured +47 % on this phantom,
    # +10 % on the shipped femoral component)
    assert _lateral_area(pv_, pf) > 1.35 * _lateral_area(v, f)


@pytest.mark.parametrize("variant, axis", [("symmetric", 0), ("symmetric-ap", 1)])
def test_symmetric_tray_is_closed_and_mirror_symmetric(variant, axis):
    v, f = tibial_component_mesh()
    sv, sf = mesh_variant(v, f, variant)
    assert np.all(_edge_use(sf) == 2) and _directed_edges_unique(sf)
    assert signed_volume(sv, sf) > 0
    centre = (v.min(0) + v.max(0)) / 2
    mirror = sv.copy()
    mirror[:, axis] = 2 * centre[axis] - mirror[:, axis]
    assert cKDTree(sv).query(mirror)[0].max() < 1e-6  # its own mirror image
    # the kept half is the input's: points on the positive side are the input's surface
    kept = sv[sv[:, axis] > centre[axis] + 1.0]
    assert cKDTree(v).query(kept)[0].max() < 1e-6
    # and the input was not symmetric to begin with (the phantom is deliberately not)
    original = v.copy()
    original[:, axis] = 2 * centre[axis] - original[:, axis]
    assert cKDTree(v).query(original)[0].max() > 1.0


def test_unknown_variant_names_the_choices():
    v, f = tibial_component_mesh()
    with pytest.raises(ValueError, match="ps-box"):
        mesh_variant(v, f, "boxy")
