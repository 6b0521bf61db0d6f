"""The workflow's command line (demo, import, find, track, batch) and the public Python API:
contracts other tools drive, exit codes, one-line errors, and the same pose everywhere."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from fluorogui.cli import main
from fluorogui.io.project.document import load_project
from fluorogui.io.project.lock import ProjectLock
from fluorogui.workflow import Session

JSON_FIELDS = {"frame", "component", "pose", "objective_mm", "per_view_mean_mm", "converged", "status", "reason",
               "seconds", "sd"}


def _cli(capsys, *args):
    """Run one command line in this process: (exit status, stdout, stderr)."""
    capsys.readouterr()
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_public_api_imports_as_documented():
    import fluorogui
    from fluorogui import FrameResult, FrameState, Placement, WorkflowSettings  # noqa: F401
    from fluorogui import Session as S

    assert S is Session and "Session" in fluorogui.__all__
    with pytest.raises(AttributeError):
        fluorogui.NoSuchThing  # noqa: B018


@pytest.mark.slow
def test_track_json_contract_resume_and_same_pose_as_the_api(demo, tmp_path, capsys):
    copy = tmp_path / "api"
    shutil.copytree(demo.parent, copy)
    code, out, err = _cli(capsys, "track", demo, "--frames", "1:1", "--json")
    assert code == 0, err
    lines = [json.loads(line) for line in out.splitlines()]
    assert [(d["frame"], d["component"]) for d in lines] == [(1, "femoral"), (1, "tibial")]
    for d in lines:
        assert set(d) == JSON_FIELDS and d["status"] == "matched" and d["converged"] is True
        assert len(d["pose"]) == 6 and len(d["per_view_mean_mm"]) == 2 and d["reason"] == ""
    stored = load_project(demo)
    assert stored.poses[(1, "femoral")].status == "matched"  # written into the project
    assert not (demo.parent / (demo.name + ".lock")).exists()  # the lock is released
    # the same frame through the Python API: the identical pose
    session = Session.open(copy / demo.name)
    api = {r.component: r.pose for r in session.match(1)}
    for component in ("femoral", "tibial"):
        np.testing.assert_array_equal(api[component], stored.poses[(1, component)].pose)
    # running again resumes: frame 1 is kept, nothing is printed for work not done
    code, out, _ = _cli(capsys, "track", demo, "--frames", "0:1", "--json")
    assert code == 0 and out.count('"status": "matched"') == 4


def test_track_reports_flagged_frames_on_stderr_and_exits_3(demo, capsys):
    session = Session.open(demo)
    session.project.sequences[1].paths[2].unlink()
    code, out, err = _cli(capsys, "track", demo, "--frames", "2:2", "--component", "tibial")
    assert code == 3
    assert err.strip().splitlines() == [
        f"fluorogui: frame 2, tibial: failed: {session.project.sequences[1].paths[2]}: file not found"]
    assert "1 failed" in out
    assert load_project(demo).poses[(2, "tibial")].reason.endswith("file not found")


def test_a_project_open_elsewhere_is_refused_by_name(demo):
    # a process of its own on purpose: the lock is re-entrant within one process
    with ProjectLock(demo, "fluorogui (desktop)"):
        run = subprocess.run([sys.executable, "-m", "fluorogui", "track", str(demo), "--frames", "1"],
                             capture_output=True, text=True, timeout=600)
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1
    assert str(demo) in run.stderr and "in use by fluorogui (desktop)" in run.stderr and str(os.getpid()) in run.stderr


@pytest.mark.parametrize("spec, problem", [("3:1", "ends before it starts"), ("x", "use A:B"),
                                           ("7", "frame 7 is not in the project"), ("20:30", "no project frame")])
def test_bad_frame_specs_are_one_line(demo, capsys, spec, problem):
    assert main(["track", str(demo), "--frames", spec]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and problem in err


def test_demo_and_import_write_projects(tmp_path, capsys):
    out = tmp_path / "d.fluoro"
    assert main(["demo", str(out), "--frames", "2"]) == 0
    project = load_project(out)
    assert project.frames == [0, 1] and "demo_truth" in project.settings
    assert all(p.is_file() for s in project.sequences for p in s.paths)
    assert main(["demo", str(out)]) == 2 and "already exists" in capsys.readouterr().err
    # the demo folder is laid out like a session folder: import it both ways
    data = tmp_path / "d_data"
    assert main(["import", str(data), "--out", str(tmp_path / "i.fluoro"), "--side", "left"]) == 0
    imported = load_project(tmp_path / "i.fluoro")
    assert imported.frames == [0, 1] and {m.component for m in imported.models} == {"femoral", "tibial"}
    assert imported.settings["kinematics"]["side"] == "left"
    assert main(["import", "--out", str(tmp_path / "e.fluoro"),
                 "--camera", str(data / "calibration/cam1.json"), "--camera", str(data / "calibration/cam2.json"),
                 "--images1", str(data / "cam1"), "--images2", str(data / "cam2"),
                 "--model", f"femoral={data / 'models/femoral_component.stl'}",
                 "--model", f"tibial={data / 'models/tibial_component.stl'}"]) == 0
    explicit = load_project(tmp_path / "e.fluoro")
    assert explicit.sequences == imported.sequences and explicit.models == imported.models
    assert main(["import", str(tmp_path), "--out", str(tmp_path / "x.fluoro")]) == 2
    assert "not a session folder" in capsys.readouterr().err


def test_import_of_unequal_cameras_warns_and_flags_later(tmp_path, capsys):
    assert main(["demo", str(tmp_path / "d.fluoro"), "--frames", "3"]) == 0
    data = tmp_path / "d_data"
    (data / "pairs.csv").unlink()
    sorted((data / "cam2").iterdir())[-1].unlink()
    capsys.readouterr()
    assert main(["import", str(data), "--out", str(tmp_path / "u.fluoro")]) == 0
    err = capsys.readouterr().err
    assert "camera 2 has 2 images but the project has 3 frames" in err
    assert len(load_project(tmp_path / "u.fluoro").sequences[1].paths) == 2


def test_find_places_both_components_and_reports_json(demo, capsys):
    from fluorogui.core.projection.pose import pose_error

    assert main(["find", str(demo), "--frames", "2", "--json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(d["frame"], d["component"], d["found"]) for d in lines] == [(2, "femoral", True), (2, "tibial", True)]
    project = load_project(demo)
    truth = project.settings["demo_truth"]["2"]
    for d in lines:
        assert set(d) == {"frame", "component", "found", "pose", "iou", "reason", "seconds"}
        e = pose_error(d["pose"], truth[d["component"]])
        # measured 0.0027 / 0.0026 mm, 0.0081 / 0.0189 deg (femoral / tibial)
        assert np.abs(e[:3]).max() < 0.0053 and np.abs(e[3:]).max() < 0.0378, e
        assert project.poses[(2, d["component"])].status == "placed"


def test_engine_problems_become_sentences():
    from fluorogui.core.matching.loop import SegmentationError
    from fluorogui.workflow import messages

    text = messages.segmentation_failed("tibial", SegmentationError(0, "outline crosses itself at point 5"))
    assert text == ("view 1: the tibial outline could not be traced, it crosses itself — edit it or re-run "
                    "Find implants")
    assert messages.plain("outline has 3 points; at least 4 are needed") == "only 3 edge points were found"
    assert "Error" not in messages.match_failed("femoral", ValueError("part of the model lies behind the X-ray source"))
