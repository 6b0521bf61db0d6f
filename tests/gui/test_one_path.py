"""One path per operation: ``fluorogui match``, the Python API (``Session.match``) and the
app's *Match* run the same per-frame matcher, so the same frame gives bit-identical poses -
including a frame that needs the ambiguity probe and one that needs occlusion masking."""
import json

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from fluorogui.cli import main  # noqa: E402
from fluorogui.core.projection.pose import rotation_matrix  # noqa: E402
from fluorogui.simulation.demo import write_stl  # noqa: E402
from fluorogui.simulation.knee_bend import build_knee_sequence  # noqa: E402
from fluorogui.simulation.phantoms import femoral_component_mesh, tibial_component_mesh  # noqa: E402
from fluorogui.workflow.framematch import occlusion_masks, turned  # noqa: E402
from fluorogui.workflow.session import Session  # noqa: E402


def _cli_match(capsys, session, frame, component, start, other=None):
    """``fluorogui match`` on the frame's files of ``session``'s project."""
    p = session.project
    args = ["match"]
    for k, view in enumerate(p.views):
        path = session.path.parent / f"cam{k + 1}.json"
        from fluorogui.io.calibration import save_view_json

        save_view_json(view, path)
        args += ["--camera", str(path)]
    args += sum((["--image", str(session.image_path(frame, k))] for k in range(session.n_views)), [])
    args += ["--model", str(p.model(component).mesh_path), "--component", component,
             "--start", *[repr(float(v)) for v in start], "--json"]
    if other is not None:
        name, pose = other
        args += ["--other", str(p.model(name).mesh_path), "--other-pose", *[repr(float(v)) for v in pose]]
    capsys.readouterr()
    code = main(args)
    out = json.loads(capsys.readouterr().out)
    return code, out


def _app_match(window, qtbot, project, frame, component, poses):
    """The app's *Match* of ``component`` in ``frame`` after placing ``poses`` by hand."""
    window.open_project(project)
    s = window.controller.session
    for name, pose in poses.items():
        s.set_pose(name, frame, pose)
    window.controller.set_frame(frame)
    with qtbot.waitSignal(window.runner.finished, timeout=600000):
        assert window.run_match(component)
    return s.pose_record(component, frame)


@pytest.mark.slow
def test_a_frame_that_needs_the_probe_gives_the_same_pose_everywhere(window, fine_demo, qtbot, capsys):
    """The tibial tray turned 35 deg about its stem converges to a false minimum that passes
    every check; the ambiguity probe (a start turned back by 20 deg) finds the truth."""
    api = Session.open(fine_demo)
    truth = api.project.settings["demo_truth"]["1"]["tibial"]
    R = rotation_matrix(*np.asarray(truth)[3:])
    start = turned(np.asarray(truth, float), api.mesh("tibial").centroid, R[:, 2], -35.0)
    api.set_pose("tibial", 1, start)
    result = api.match(1, "tibial")[0]
    assert result.recovered == "probe"  # this frame needs the probe
    code, out = _cli_match(capsys, api, 1, "tibial", start)
    record = _app_match(window, qtbot, fine_demo, 1, "tibial", {"tibial": start})
    np.testing.assert_array_equal(out["pose"], result.pose)
    np.testing.assert_array_equal(record.pose, result.pose)
    assert out["status"] == result.status == record.status and code == (0 if result.status == "matched" else 3)


@pytest.fixture(scope="module")
def overlapping(tmp_path_factory):
    """A generated knee bend of the phantom components that overlap in the lateral view."""
    folder = tmp_path_factory.mktemp("bend")
    meshes = {}
    for name, mesh in (("femoral", femoral_component_mesh()), ("tibial", tibial_component_mesh())):
        meshes[name] = folder / f"{name}.stl"
        write_stl(meshes[name], *mesh)
    return build_knee_sequence(folder / "knee", meshes["femoral"], meshes["tibial"], frames=1, image_size=512, seed=3)


@pytest.mark.slow
def test_a_frame_that_needs_occlusion_masks_gives_the_same_pose_everywhere(window, overlapping, qtbot, capsys):
    api = Session.open(overlapping)
    truth = {c: np.asarray(p, float) for c, p in api.project.settings["truth"]["0"].items()}
    start = truth["tibial"] + np.array([1.0, -1.0, 1.5, 2.0, -2.0, 1.5])
    masks = occlusion_masks(api.views, [(api.mesh("femoral"), truth["femoral"])], start, api.mesh("tibial"))
    assert masks is not None  # the femoral component overlaps the tray's outline: this frame needs the mask
    poses = {"femoral": truth["femoral"], "tibial": start}
    for name, pose in poses.items():
        api.set_pose(name, 0, pose)
    result = api.match(0, "tibial")[0]
    code, out = _cli_match(capsys, api, 0, "tibial", start, other=("femoral", truth["femoral"]))
    record = _app_match(window, qtbot, overlapping, 0, "tibial", poses)
    np.testing.assert_array_equal(out["pose"], result.pose)
    np.testing.assert_array_equal(record.pose, result.pose)
    assert out["status"] == result.status == record.status
    assert np.abs(result.pose - truth["tibial"])[:3].max() < 0.1  # and it is right
