"""Find implants with the other component present: where the components overlap in a view,
each is searched with the ones already found masked (edge maps, fit, verdict), so both are
found. The images come from the independent X-ray model (``fluorogui.reference.xray``)."""
import numpy as np
import pytest

import fluorogui.core.search.find as find
from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import motion_between, rotation_matrix, transform_points
from fluorogui.core.projection.silhouette import projected_region
from fluorogui.io.meshes.read import load_mesh
from fluorogui.reference.xray import MU_METAL, Body, XrayModel, xray_image
from fluorogui.simulation.knee_bend import knee_bend_truth, sequence_views


@pytest.fixture(scope="module")
def overlapping(shared_data):
    """The real components in a knee at 60 deg with the tray 4 mm closer to the femoral
    component than in the bend: in the lateral view the femoral component covers a fifth
    of the tray."""
    models = shared_data / "biplane-tka" / "models"
    meshes = {c: load_mesh(models / f"{c}_component.stl") for c in ("femoral", "tibial")}
    views = sequence_views(1024, "right")
    truth = {c: np.asarray(p, float) for c, p in
             knee_bend_truth(meshes["femoral"][0], meshes["tibial"][0], [60.0])[0].items()}
    truth["tibial"][:3] += (0.0, 0.0, 4.0)
    bodies = [Body(transform_points(truth[c], np.asarray(v, float)), f, MU_METAL) for c, (v, f) in meshes.items()]
    rng = np.random.default_rng(0)
    images = [xray_image(view, bodies, XrayModel(bits=8, photons=3000), rng) for view in views]
    return views, images, {c: prepare_mesh(*m) for c, m in meshes.items()}, truth


def _hidden_share(views, prepared, truth):
    def region(view, c):
        return projected_region(view, [(prepared[c], rotation_matrix(*truth[c][3:]), truth[c][:3])], 0)
    return [float((region(v, "femoral") & region(v, "tibial")).sum() / region(v, "tibial").sum()) for v in views]


@pytest.mark.slow
def test_both_components_are_found_where_they_overlap(overlapping):
    views, images, prepared, truth = overlapping
    assert max(_hidden_share(views, prepared, truth)) > 0.15  # the scene is what it says
    found = find.find_components(images, views, prepared)
    # measured 0.136 mm / 0.275 deg (the femoral component, found first, with the tray's
    # edges in its outline) and 0.062 mm / 0.102 deg: starts for the masked match that follows
    limits = {"femoral": (0.28, 0.55), "tibial": (0.13, 0.21)}
    for c, p in found.items():
        assert p.found, (c, p.reason)
        mm, deg = motion_between(p.pose, truth[c], prepared[c].centroid)
        assert mm < limits[c][0] and deg < limits[c][1], (c, mm, deg)


@pytest.mark.slow
def test_without_the_mask_the_hidden_tray_is_not_found(overlapping, monkeypatch):
    views, images, prepared, _ = overlapping
    monkeypatch.setattr(find, "projected_region", lambda view, placed, margin: np.zeros(view.image_size[::-1], bool))
    assert not find.find_components(images, views, prepared)["tibial"].found
