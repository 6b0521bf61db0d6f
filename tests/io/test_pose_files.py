"""Pose files: Autoscoper .tra and JointTrack .jts round trips (the real JointTrack file with
its calibration included), our CSVs, and bad files refused by line."""
from __future__ import annotations

import numpy as np
import pytest

from fluorogui.core.projection.pose import pose_to_matrix
from fluorogui.io.calibration import load_view
from fluorogui.io.errors import InputError
from fluorogui.io.files import check_output_file
from fluorogui.io.pose_files import (
    jointtrack_to_world_pose,
    pose_to_jointtrack,
    read_jts,
    read_long_poses,
    read_pose_csv,
    read_tra,
    write_csv,
    write_jts,
    write_tra,
)


def test_tra_round_trip_with_missing_poses(tmp_path):
    rng = np.random.default_rng(0)
    poses = [pose_to_matrix(np.r_[rng.normal(size=3) * 50, rng.uniform(-180, 180, 3)]) for _ in range(4)]
    rows = [[poses[0], poses[1]], [None, poses[2]], [poses[3], None]]
    write_tra(tmp_path / "t.tra", rows)
    text = (tmp_path / "t.tra").read_text().splitlines()
    assert len(text) == 3 and len(text[0].split(",")) == 32
    assert text[1].split(",")[:16] == ["NaN"] * 16
    back = read_tra(tmp_path / "t.tra", 2)
    assert back[1][0] is None and back[2][1] is None
    assert np.abs(back[0][1] - poses[1]).max() < 1e-9
    assert np.abs(back[2][0] - poses[3]).max() < 1e-9


def test_tra_with_the_wrong_column_count_names_the_line(tmp_path):
    (tmp_path / "t.tra").write_text(",".join(["1"] * 32) + "\n" + ",".join(["1"] * 31) + "\n")
    with pytest.raises(InputError, match="line 1.*not a rigid|line 2 has 31 numbers; expected 32"):
        read_tra(tmp_path / "t.tra", 2)
    eye = ",".join(str(v) for v in np.eye(4).reshape(16))
    (tmp_path / "t.tra").write_text(f"{eye},{eye}\n{eye}\n")
    with pytest.raises(InputError, match="line 2 has 16 numbers; expected 32"):
        read_tra(tmp_path / "t.tra", 2)


def test_jointtrack_camera_frame_round_trip(tmp_path, shared_data):
    """The real fem.jts, read into our world frame with its calibration and written back,
    gives the same numbers (JT_INTCALIB's world is JointTrack's camera frame)."""
    folder = shared_data / "single-plane-tka"
    view = load_view(folder / "calibration.txt")
    rows = read_jts(folder / "fem.jts")
    assert len(rows) == 3 and rows[0][2] == pytest.approx(-1027.713)
    world = [jointtrack_to_world_pose(r, view) for r in rows]
    write_jts(tmp_path / "fem.jts", [pose_to_jointtrack(p, view) for p in world])
    again = read_jts(tmp_path / "fem.jts")
    for a, b in zip(rows, again):
        assert np.abs(a - b).max() < 1e-6  # written with 7 decimals
    lines = (tmp_path / "fem.jts").read_text().splitlines()
    assert lines[0] == "JT_EULER_312" and "z_rot" in lines[1]


def test_jointtrack_rows_in_a_tilted_view_map_back_to_the_same_pose():
    from fluorogui.core.projection.geometry import View

    c, s = np.cos(0.4), np.sin(0.4)
    view = View(source=(100.0, -20.0, 900.0), normal=(s, 0.0, -c), e_u=(c, 0.0, s), e_v=(0.0, -1.0, 0.0),
                distance=1100.0, pitch=(0.3, 0.3), principal_point=(511.5, 511.5), image_size=(1024, 1024))
    pose = np.array([10.0, -5.0, 30.0, 40.0, -20.0, 15.0])
    row = pose_to_jointtrack(pose, view)
    assert np.abs(pose_to_matrix(jointtrack_to_world_pose(row, view)) - pose_to_matrix(pose)).max() < 1e-9
    # the camera frame: the model's origin in front of the source lies at negative Z
    assert row[2] < 0


def test_jts_not_optimized_and_bad_rows(tmp_path):
    write_jts(tmp_path / "a.jts", [np.arange(6.0), None])
    assert (tmp_path / "a.jts").read_text().splitlines()[3] == "NOT_OPTIMIZED"
    rows = read_jts(tmp_path / "a.jts")
    assert rows[1] is None and rows[0] == pytest.approx(np.arange(6.0))
    (tmp_path / "b.jts").write_text("JT_EULER_312\nx,y,z,zr,xr,yr\n1,2,3,4,5\n")
    with pytest.raises(InputError, match="line 3 has 5 columns; expected 6"):
        read_jts(tmp_path / "b.jts")
    (tmp_path / "c.jts").write_text("EULER\n1,2,3,4,5,6\n")
    with pytest.raises(InputError, match="JT_EULER_312"):
        read_jts(tmp_path / "c.jts")


def test_long_and_wide_pose_csvs(tmp_path):
    (tmp_path / "long.csv").write_text(
        "frame,component,x,y,z,alpha,beta,gamma\n0,femoral,1,2,3,4,5,6\n0,tibial,1,2,3,4,5,NaN\n")
    poses = read_pose_csv(tmp_path / "long.csv")
    assert poses[(0, "femoral")] == pytest.approx([1, 2, 3, 4, 5, 6])
    assert np.isnan(poses[(0, "tibial")][5])
    header = ["frame", *(f"femoral_{k}" for k in "x y z alpha beta gamma".split())]
    write_csv(tmp_path / "wide.csv", ["a comment"], header, [[3, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]])
    assert (tmp_path / "wide.csv").read_text().startswith("# a comment\nframe,femoral_x")
    assert read_pose_csv(tmp_path / "wide.csv")[(3, "femoral")] == pytest.approx([1, 2, 3, 4, 5, 6])


@pytest.mark.parametrize("text, words", [
    ("frame,component,x,y,z,alpha,beta\n", "lacks the column gamma"),
    ("frame,component,x,y,z,alpha,beta,gamma\n0,femur,1,2,3,4,5,6\n", "component 'femur'"),
    ("frame,component,x,y,z,alpha,beta,gamma\n0,femoral,1,2,3,4,5\n", "line 2 has 7 values"),
    ("frame,component,x,y,z,alpha,beta,gamma\n0,femoral,1,2,x,4,5,6\n", "line 2, z: 'x' is not a number"),
    ("frame,component,x,y,z,alpha,beta,gamma\n0,femoral,1,2,3,4,5,6\n0,femoral,1,2,3,4,5,6\n", "second femoral"),
])
def test_bad_long_pose_csvs_are_refused_by_row(tmp_path, text, words):
    (tmp_path / "p.csv").write_text(text)
    with pytest.raises(InputError, match=words):
        read_long_poses(tmp_path / "p.csv")


def test_unwritable_outputs_are_refused_before_work(tmp_path):
    with pytest.raises(InputError, match="folder does not exist"):
        check_output_file(tmp_path / "nowhere" / "out.csv")
    with pytest.raises(InputError, match="is a folder"):
        check_output_file(tmp_path)
