"""Shared fixtures of the core tests: the phantom tibial tray posed at 45 degrees."""
import pytest

from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import transform_points
from fluorogui.simulation.phantoms import tibial_component_mesh
from fluorogui.simulation.protocols import flexion_pose


@pytest.fixture(scope="module")
def tray():
    """(prepared mesh, pose, world vertices) of the phantom tray at 45 degrees of flexion."""
    v, f = tibial_component_mesh()
    mesh = prepare_mesh(v, f)
    pose = flexion_pose(mesh.vertices, 45.0)
    return mesh, pose, transform_points(pose, mesh.vertices)
