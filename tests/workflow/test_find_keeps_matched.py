"""Nothing replaces a matched pose without saying so (issue 44, item 4): *find implants*
and imported poses keep matched and accepted poses unless told to replace them, and say
what they did. Before, ``fluorogui find demo.fluoro --frames 0`` after a track turned frame
0's matched poses into placed ones, silently."""
from __future__ import annotations

import json

import numpy as np

from fluorogui.cli import main
from fluorogui.core.status import Status
from fluorogui.io.project.document import load_project
from fluorogui.workflow import Session
from fluorogui.workflow.exports import export_poses_csv, import_poses


def test_find_on_the_command_line_keeps_matched_poses_and_says_so(demo, capsys):
    before = load_project(demo).poses[(0, "femoral")]
    assert before.status == Status.MATCHED  # the demo fixture matched frame 0
    assert main(["find", str(demo), "--frames", "0", "--json"]) == 0
    out, err = capsys.readouterr()
    rows = [json.loads(line) for line in out.splitlines()]
    assert [(r["component"], r["kept"]) for r in rows] == [("femoral", True), ("tibial", True)]
    assert "frame 0, femoral: kept its matched pose; --replace searches for it again" in err
    after = load_project(demo).poses[(0, "femoral")]
    assert after.status == Status.MATCHED and np.array_equal(after.pose, before.pose)


def test_find_replace_searches_again_and_says_so(demo, capsys):
    assert main(["find", str(demo), "--frames", "0", "--component", "femoral", "--replace"]) == 0
    assert "frame 0, femoral: replaced its matched pose (--replace)" in capsys.readouterr().err
    project = load_project(demo)
    assert project.poses[(0, "femoral")].status == Status.PLACED
    assert project.poses[(0, "tibial")].status == Status.MATCHED  # not asked for


def test_session_find_searches_only_what_is_not_matched(demo):
    session = Session.open(demo)
    session.set_pose("tibial", 0, session.pose("tibial", 0))  # placed by hand: no longer matched
    assert session.matched_in(0) == ["femoral"]
    placements = session.find(0)
    assert list(placements) == ["tibial"]
    assert session.pose_record("femoral", 0).status == Status.MATCHED


def test_imported_poses_keep_matched_ones_unless_replacing(demo, tmp_path):
    source = Session.open(demo)
    for c in source.components():
        source.set_pose(c, 0, source.pose(c, 0) + [1.0, 0, 0, 0, 0, 0])
    export_poses_csv(source, tmp_path / "poses.csv")
    session = Session.open(demo)
    kept = []
    count = import_poses(session, tmp_path / "poses.csv", kept=kept)
    assert kept == [(0, "femoral"), (0, "tibial")] and count == 0  # (only frame 0 has poses)
    assert session.pose_record("femoral", 0).status == Status.MATCHED
    import_poses(session, tmp_path / "poses.csv", replace=True)
    assert session.pose_record("femoral", 0).status == Status.PLACED
