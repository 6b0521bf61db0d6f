"""The weak-view rule end to end: a generated frame where one view's edges are weak and
nothing else is wrong, through ``Session.match``.

A dense layer lies over the lower part of view 1 (its transmission falls smoothly to 3 %
below the tray's middle row): behind it the tray's edges are ~30 times fainter than the
rest of the outline, so Canny's thresholds (fractions of the crop's strongest gradient)
leave them out, while the outline the matcher follows is still found. The pose is right
and fits both outlines; only edge support in view 1 fails, so the pose is judged by
view 2 alone, which cannot see depth along its own axis: the flag names that direction.
"""
import re

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
def test_a_view_with_weak_edges_is_named_with_what_the_other_view_leaves_loose(frame):
    path, truth = frame
    result = _match_tray(path, truth)  # the clean frame first: matched
    assert result.status == "matched", result.reason
    session = Session.open(path)
    image_path = session.project.sequences[0].paths[0]
    rows = session.views[0].project(transform_points(truth["tibial"], session.mesh("tibial").vertices))[:, 1]
    write_image(image_path, _layer(read_image(image_path), float(np.median(rows)), 0.03), bits=8)

    result = _match_tray(path, truth)
    error = pose_error(result.pose, truth["tibial"])
    # measured 0.015 mm / 0.021 deg: a right pose, flagged only for what view 2 cannot see
    assert np.abs(error[:3]).max() < 0.03 and np.abs(error[3:]).max() < 0.05, error
    assert result.status == "needs_review" and "edge_support" in result.failed
    assert not set(result.failed) - {"edge_support", "time"}  # time: recovery starts on a busy machine
    # measured: 56 % on edges in view 1, depth along view 2's axis uncertain to +-0.48 mm
    found = re.search(r"view 1 has little edge contrast \(only (\d+) % of the model outline lies on image edges "
                      r"there\); judged by the other view, its depth along view 2's axis is uncertain to "
                      r"±(\d\.\d+) mm", result.reason)
    assert found, result.reason
    assert 40 <= int(found.group(1)) < 85 and 0.3 < float(found.group(2)) < 0.7
    assert "in view 2" not in result.reason  # view 2's edges carry it
