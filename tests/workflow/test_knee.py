"""A session's knee: side and anatomical frames (undoable, saved), kinematics per frame with
status and reasons, exports that round-trip through imports, and the command line."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fluorogui.cli import main
from fluorogui.core.knee.kinematics import knee_kinematics, relative_pose_from_kinematics
from fluorogui.core.projection.pose import matrix_to_pose, pose_to_matrix
from fluorogui.core.records import PoseRecord
from fluorogui.core.status import Status
from fluorogui.io.errors import InputError
from fluorogui.io.pose_files import read_jts, read_tra
from fluorogui.workflow import Session
from fluorogui.workflow.exports import (
    export_jts,
    export_kinematics_csv,
    export_poses_csv,
    export_tra,
    import_poses,
)


def put_truth(session, truth, frames=None):
    for frame, by in truth(session).items():
        if frames is None or frame in frames:
            for c, pose in by.items():
                session.project.poses[(frame, c)] = PoseRecord(pose)


def test_matched_frame_kinematics_agree_with_the_truth(demo, truth):
    session = Session.open(demo)
    t = truth(session)[0]
    expected = knee_kinematics(pose_to_matrix(t["femoral"]), pose_to_matrix(t["tibial"]),
                               session.anatomical_frame("femoral"), session.anatomical_frame("tibial"))
    row = session.knee_at(0)
    assert row.status == "matched", row.reason
    # measured on frame 0: 0.0186 / 0.0022 / 0.0148 deg and 0.0109 / 0.0066 / 0.0028 mm off
    assert np.abs(row.values.values() - expected.values())[:3].max() < 0.03
    assert np.abs(row.values.values() - expected.values())[3:].max() < 0.022


def test_missing_and_flagged_frames(demo):
    session = Session.open(demo)
    rows = {r.frame: r for r in session.knee_rows()}
    assert rows[1].status == "missing" and "femoral or tibial" in rows[1].reason
    assert np.all(np.isnan(rows[1].values.values()))
    record = session.pose_record("tibial", 0)
    session.project.poses[(0, "tibial")] = PoseRecord(record.pose, record.match, status=Status.NEEDS_REVIEW,
                                                      reason="residual 3x typical")
    row = session.knee_at(0)
    assert row.status == "needs_review" and "tibial needs review (residual 3x typical)" in row.reason
    assert np.all(np.isfinite(row.values.values()))


def test_curves_of_a_single_matched_frame_span_the_sessions_frames(demo):
    """The demo's one matched frame (the others have no poses): autoscale gave the x axis
    +-0.05 around it, ticks at -0.045 ... 0.045 written over each other."""
    from matplotlib.figure import Figure

    from fluorogui.workflow.knee_plot import draw_kinematics

    session = Session.open(demo)
    rows = session.knee_rows()
    assert sum(r.status != "missing" for r in rows) == 1
    figure = Figure()
    axes = draw_kinematics(figure, rows)
    for ax in axes:
        lo, hi = ax.get_xlim()
        assert (lo, hi) == (-0.5, len(rows) - 0.5)
        ticks = [t for t in ax.get_xticks() if lo <= t <= hi]
        assert ticks and all(float(t).is_integer() for t in ticks)
    axes = draw_kinematics(figure, rows, against="flexion")
    flexion = rows[0].values.flexion_deg
    assert axes[0].get_xlim()[1] - axes[0].get_xlim()[0] >= 1.0
    assert axes[0].get_xlim()[0] < flexion < axes[0].get_xlim()[1]


def test_side_and_frames_are_undoable_and_saved(demo):
    session = Session.open(demo)
    assert session.side is None
    session.set_side("left")
    assert session.side == "left" and session.dirty
    session.history.undo()
    assert session.side is None
    session.history.redo()
    default = session.anatomical_frame("femoral")
    turned = default @ np.array([[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    session.set_anatomical_frame("femoral", turned)
    assert session.anatomical_frame_source("femoral") == "user"
    session.save()
    again = Session.open(demo)
    assert again.side == "left"
    assert np.abs(again.anatomical_frame("femoral") - turned).max() < 1e-12
    again.reset_anatomical_frame("femoral")
    assert np.abs(again.anatomical_frame("femoral") - default).max() < 1e-12
    with pytest.raises(ValueError, match="determinant"):
        again.set_anatomical_frame("tibial", np.diag([1.0, 1.0, -1.0, 1.0]))


def test_left_knee_flips_the_mirrored_signs(demo, truth):
    session = Session.open(demo)
    put_truth(session, truth)
    right = session.knee_at(1).values.values()
    session.set_side("left")
    left = session.knee_at(1).values.values()
    assert left[[0, 4, 5]] == pytest.approx(right[[0, 4, 5]], abs=1e-12)
    assert left[[1, 2, 3]] == pytest.approx(-right[[1, 2, 3]], abs=1e-12)


def test_exports_round_trip_through_imports(demo, truth, tmp_path):
    session = Session.open(demo)
    put_truth(session, truth, frames=[0, 1, 2])
    frames = session.frames
    export_poses_csv(session, tmp_path / "poses.csv")
    export_kinematics_csv(session, tmp_path / "kin.csv")
    export_tra(session, tmp_path / "poses.tra")
    export_jts(session, tmp_path / "jts", view=1)

    text = (tmp_path / "poses.csv").read_text()
    assert "# fluorogui " in text and "side: right (not set" in text and "Grood & Suntay" in text
    kin = [line for line in (tmp_path / "kin.csv").read_text().splitlines() if not line.startswith("#")]
    assert kin[0] == "frame,flexion_deg,varus_deg,internal_deg,medial_mm,anterior_mm,distraction_mm,status,reason"
    assert len(kin) == 1 + len(frames) and kin[-1].split(",")[1] == "NaN"
    tra = (tmp_path / "poses.tra").read_text().splitlines()
    assert len(tra) == len(frames) and tra[-1].split(",")[0] == "NaN"

    for source, kwargs in ((tmp_path / "poses.tra", {}), (tmp_path / "poses.csv", {}),
                           (tmp_path / "jts" / "tibial.jts", {"component": "tibial", "view": 1})):
        fresh = Session.open(demo)
        fresh.project.poses.clear()
        count = import_poses(fresh, source, **kwargs)
        assert count == (6 if "component" not in kwargs else 3)
        for (frame, c), record in fresh.project.poses.items():
            expected = pose_to_matrix(truth(fresh)[frame][c])
            assert np.abs(pose_to_matrix(record.pose) - expected).max() < (1e-6 if ".jts" in str(source) else 1e-8)
            assert record.status == "placed" and source.name in record.reason
        fresh.history.undo()  # one step
        assert not fresh.project.poses


def test_kinematics_cli_contract(tmp_path, capsys):
    femur = np.eye(4)
    relative = relative_pose_from_kinematics([45.0, 2.0, -3.0, 1.0, 2.0, 5.0], "left")
    rows = ["frame,component,x,y,z,alpha,beta,gamma",
            "0,femoral," + ",".join(str(v) for v in matrix_to_pose(femur)),
            "0,tibial," + ",".join(str(v) for v in matrix_to_pose(femur @ relative)),
            "1,femoral," + ",".join(str(v) for v in matrix_to_pose(femur))]
    (tmp_path / "poses.csv").write_text("\n".join(rows) + "\n")
    identity = tmp_path / "eye.json"
    identity.write_text(json.dumps({"matrix": np.eye(4).tolist()}))
    code = main(["kinematics", "--poses", str(tmp_path / "poses.csv"), "--side", "left", "--femoral-frame",
                 str(identity), "--tibial-frame", str(identity), "--out", str(tmp_path / "out.csv")])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "1 frame written as NaN (tibial pose missing)" in err
    lines = [line for line in (tmp_path / "out.csv").read_text().splitlines() if not line.startswith("#")]
    assert lines[0] == "frame,flexion_deg,varus_deg,internal_deg,medial_mm,anterior_mm,distraction_mm"
    assert [float(v) for v in lines[1].split(",")] == pytest.approx([0, 45, 2, -3, 1, 2, 5], abs=1e-8)
    assert lines[2].split(",")[1:] == ["NaN"] * 6
    assert "# frame 1: NaN: tibial pose missing" in (tmp_path / "out.csv").read_text()


@pytest.mark.parametrize("matrix, words", [
    (np.diag([1.0, 1.0, 1.0 + 1e-3, 1.0]).tolist(), "not orthonormal"),
    (np.diag([1.0, -1.0, 1.0, 1.0]).tolist(), "determinant"),
])
def test_kinematics_cli_refuses_frames_that_are_not_rotations(tmp_path, capsys, matrix, words):
    (tmp_path / "poses.csv").write_text("frame,component,x,y,z,alpha,beta,gamma\n0,femoral,0,0,0,0,0,0\n")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"matrix": matrix}))
    code = main(["kinematics", "--poses", str(tmp_path / "poses.csv"), "--side", "right", "--femoral-frame",
                 str(bad), "--tibial-frame", str(bad), "--out", str(tmp_path / "out.csv")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "bad.json" in err and words in err
    assert not (tmp_path / "out.csv").exists()


def test_tra_and_jts_leave_out_poses_flagged_for_review_unless_asked(demo, truth, tmp_path, capsys):
    # .tra and .jts carry no status: a pose the matcher flagged must not pass as matched there
    from fluorogui.workflow.exports import unreviewed_matches

    session = Session.open(demo)
    put_truth(session, truth, frames=[0, 1, 2])
    flagged_pose = np.asarray(truth(session)[1]["femoral"], dtype=float) + [2.0, 0, 0, 0, 0, 0]
    session.project.poses[(1, "femoral")] = PoseRecord(flagged_pose, status=Status.NEEDS_REVIEW,
                                                       reason="residual too high")
    assert unreviewed_matches(session) == [(1, "femoral", "residual too high")]

    def tra_rows(**kwargs):
        export_tra(session, tmp_path / "p.tra", **kwargs)
        return read_tra(tmp_path / "p.tra", 2)

    def jts_rows(**kwargs):
        export_jts(session, tmp_path / "jts", view=0, **kwargs)
        return [row is not None for row in read_jts(tmp_path / "jts" / "femoral.jts")]

    rows = tra_rows()
    assert rows[1][0] is None and rows[1][1] is not None and rows[0][0] is not None  # only that pose left out
    assert jts_rows()[:3] == [True, False, True]  # JointTrack's NOT_OPTIMIZED row
    rows = tra_rows(include_unreviewed=True)
    assert np.allclose(matrix_to_pose(rows[1][0]), flagged_pose) and jts_rows(include_unreviewed=True)[1]
    session.set_reviewed("femoral", 1)  # accepted: written like any other
    assert unreviewed_matches(session) == [] and tra_rows()[1][0] is not None
    session.set_reviewed("femoral", 1, False)
    session.save()
    out = tmp_path / "cli.tra"
    capsys.readouterr()
    code = main(["export", str(demo), "--tra", str(out)])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "1 pose flagged for review and left out" in err and "frame 1" in err
    assert out.read_text().splitlines()[1].split(",")[0] == "NaN"


def test_export_refuses_an_unwritable_path_before_work(demo, tmp_path, capsys):
    code = main(["export", str(demo), "--poses", str(tmp_path / "p.csv"), "--kinematics",
                 str(tmp_path / "missing" / "k.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "missing/k.csv" in err and "folder does not exist" in err
    assert not (tmp_path / "p.csv").exists()
    code = main(["export", str(demo), "--jts", str(tmp_path / "j")])
    assert code == 2 and "--jts and --view go together" in capsys.readouterr().err


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG"), (".svg", b"<?xml"), (".pdf", b"%PDF")])
def test_figure_export_formats(demo, truth, tmp_path, suffix, magic):
    from fluorogui.workflow.exports import export_plot

    session = Session.open(demo)
    put_truth(session, truth)
    out = tmp_path / "out"
    out.mkdir()
    path = export_plot(session, out / f"k{suffix}", against="flexion")
    assert path.read_bytes()[:len(magic)] == magic
    assert [p.name for p in out.iterdir()] == [f"k{suffix}"]  # no temporary left
    with pytest.raises(InputError, match="must be .png, .svg or .pdf"):
        export_plot(session, out / "k.jpg")


def test_match_sds_become_kinematics_sds_and_export_columns(demo, truth, tmp_path):
    from fluorogui.core.records import MatchRecord

    session = Session.open(demo)
    for c, pose in truth(session)[1].items():
        match = MatchRecord(0.05, [0.05, 0.05], 10, 0.1, True, "fast",
                            quality={"sd": [0.01, 0.02, 0.01, 0.03, 0.02, 0.01]})
        session.project.poses[(1, c)] = PoseRecord(pose, match)
    row = session.knee_at(1)
    assert row.status == "matched" and np.all(np.isfinite(row.sd)) and np.all(row.sd > 0)
    export_poses_csv(session, tmp_path / "p.csv")
    lines = [line for line in (tmp_path / "p.csv").read_text().splitlines() if not line.startswith("#")]
    header = lines[0].split(",")
    one = dict(zip(header, lines[2].split(",")))
    assert float(one["femoral_sd_y"]) == pytest.approx(0.02)
    assert float(one["flexion_deg_sd"]) == pytest.approx(row.sd[0])


def test_a_one_component_session_exports_poses_with_nan_kinematics(demo, truth, tmp_path):
    session = Session.open(demo)
    put_truth(session, truth)
    session.project.models = [m for m in session.project.models if m.component == "femoral"]
    rows = session.knee_rows()
    assert all(r.status == "missing" and r.reason == "no tibial model in this session" for r in rows)
    assert all(np.all(np.isnan(r.values.values())) for r in rows)
    export_poses_csv(session, tmp_path / "p.csv")
    data = [line for line in (tmp_path / "p.csv").read_text().splitlines() if not line.startswith("#")]
    row = dict(zip(data[0].split(","), data[1].split(",")))
    assert float(row["femoral_x"]) == pytest.approx(truth(session)[0]["femoral"][0])


def test_a_matchs_body_covariance_gives_the_kinematics_sds_and_is_saved(demo, truth, tmp_path):
    """Where both matches kept the body's covariance (``MatchResult.cov_body``) the knee's
    SDs come from it, not from the Euler angles' SDs taken as independent."""
    from fluorogui.core.knee.kinematics import kinematics_sd_body
    from fluorogui.core.records import MatchRecord

    session = Session.open(demo)
    poses = truth(session)[1]
    cov = np.diag([0.01, 0.02, 0.01, 0.05, 0.04, 0.03]) ** 2
    cov[3, 4] = cov[4, 3] = -0.5 * 0.05 * 0.04
    for c, pose in poses.items():
        quality = {"sd": [0.01, 0.02, 0.01, 3.0, 3.0, 0.01], "cov_body": cov.tolist()}
        session.project.poses[(1, c)] = PoseRecord(pose, MatchRecord(0.05, [0.05, 0.05], 10, 0.1, True, "fast",
                                                                     quality=quality))
    expected = kinematics_sd_body(pose_to_matrix(poses["femoral"]), pose_to_matrix(poses["tibial"]),
                                  session.anatomical_frame("femoral"), session.anatomical_frame("tibial"),
                                  side="right", femoral_cov=cov, tibial_cov=cov,
                                  femoral_centroid=session.mesh("femoral").centroid,
                                  tibial_centroid=session.mesh("tibial").centroid)
    assert session.knee_at(1).sd == pytest.approx(expected, rel=1e-9)
    assert session.knee_at(1).sd[0] < 0.2  # not the 3 deg Euler SDs
    session.save(tmp_path / "k.fluoro")
    again = Session.open(tmp_path / "k.fluoro")
    assert again.knee_at(1).sd == pytest.approx(expected, rel=1e-9)
    # an older project (the Euler SDs only) keeps the old propagation
    for c in poses:
        del again.project.poses[(1, c)].match.quality["cov_body"]
    assert again.knee_at(1).sd[0] > 1.0

