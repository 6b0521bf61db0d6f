"""The weak-view rule end to end: a generated frame where one view's edges are weak and
nothing else is wrong, through ``Session.match``.

A dense layer lies over the lower part of view 1 (its transmission falls smoothly to 3 %
below the tray's middle row): behind it the tray's edges are ~30 times fainter than the
rest of the outline, so Canny's thresholds (fractions of the crop's strongest gradient)
leave them out, while the outline the matcher follows is still found. The pose is right
and fits both outlines; only edge support in view 1 fails, so the pose is judged by
view 2 and the edges view 1 still has (its upper half): together they pin it, and the
right pose is matched, not flagged. (Judged by view 2 alone, as the rule first did, its
depth along view 2's axis was uncertain to ±0.48 mm and the right pose was flagged.)
"""
import numpy as np
import pytest

from fluorogui import Session
from fluorogui.core.projection.pose import pose_error, transform_points
from fluorogui.io.images import read_image, write_image
from fluorogui.simulation.knee_bend import build_knee_sequence

OFFSET = np.array([0.5, -0.5, 0.5, 0.5, -0.5, 0.5])


def _layer(image: np.ndarray, from_row: float, transmission: float, ramp_px: float = 30.0) -> np.ndarray:
    rows = np.arange(image.shape[0], dtype=np.float32)[:, None]
    return image * (1.0 + (transmission - 1.0) * np.clip((rows - from_row) / ramp_px, 0.0, 1.0))


@pytest.fixture(scope="module")
def frame(shared_data, tmp_path_factory):
    models = shared_data / "biplane-tka" / "models"
    path = build_knee_sequence(tmp_path_factory.mktemp("weak"), models / "femoral_component.stl",
                               models / "tibial_component.stl", frames=1, seed=0)
    session = Session.open(path)
    truth = {c: np.asarray(p, float) for c, p in session.project.settings["truth"]["0"].items()}
    return path, truth


def _match_tray(path, truth):
    session = Session.open(path)
    session.set_pose("femoral", 0, truth["femoral"])
    session.set_pose("tibial", 0, truth["tibial"] + OFFSET)
    (result,) = session.match(0, "tibial")
    return result


@pytest.mark.slow
def test_a_view_with_weak_edges_is_judged_by_the_edges_it_has_and_the_other_view(frame):
    path, truth = frame
    result = _match_tray(path, truth)  # the clean frame first: matched
    assert result.status == "matched", result.reason
    session = Session.open(path)
    image_path = session.project.sequences[0].paths[0]
    rows = session.views[0].project(transform_points(truth["tibial"], session.mesh("tibial").vertices))[:, 1]
    write_image(image_path, _layer(read_image(image_path), float(np.median(rows)), 0.03), bits=8)

    result = _match_tray(path, truth)
    error = pose_error(result.pose, truth["tibial"])
    # measured 0.015 mm / 0.021 deg: a right pose
    assert np.abs(error[:3]).max() < 0.03 and np.abs(error[3:]).max() < 0.05, error
    # view 1's edges are weak (measured 56 % of the outline on edges, the limit 85 %) ...
    edge = result.quality.edge_support
    assert 0.4 < edge[0] < 0.85 and edge[1] >= 0.85, edge
    # ... but what they show and view 2 pin the pose: matched, nothing flagged
    assert result.status == "matched" and not result.failed, result.reason
