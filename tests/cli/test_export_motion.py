"""The command line's time base and motion exports: ``import --fps`` and a video's own rate,
``export --c3d/--mot/--trc/--xromm`` with ``--fps``, the one-line refusals, and the
read-back errors of one run: the C3D's markers against the poses CSV written beside it
(its 4×4s and anatomical frames), the .mot against the kinematics CSV."""
from __future__ import annotations

import csv
import json

import cv2
import numpy as np
import pytest

from fluorogui.cli import main
from fluorogui.core.records import PoseRecord
from fluorogui.core.status import Status
from fluorogui.io.project.document import load_project
from fluorogui.workflow import Session


@pytest.fixture(scope="module")
def demo_with_truth(tmp_path_factory):
    """A three-frame demo whose true poses are stored as matched (saved)."""
    folder = tmp_path_factory.mktemp("motion_cli")
    assert main(["demo", str(folder / "d.fluoro"), "--frames", "3"]) == 0
    session = Session.open(folder / "d.fluoro")
    for frame, by in session.project.settings["demo_truth"].items():
        for c, pose in by.items():
            session.project.poses[(int(frame), c)] = PoseRecord(np.asarray(pose, float), status=Status.MATCHED)
    session.save()
    return folder / "d.fluoro"


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def test_export_needs_a_frame_rate_and_says_so_in_one_line(demo_with_truth, tmp_path, capsys):
    for option in ("--c3d", "--trc", "--mot"):
        out = tmp_path / f"m{option[2:]}"
        assert main(["export", str(demo_with_truth), option, str(out)]) == 2
        err = one_error_line(capsys)
        assert option in err and "frame rate" in err and "--fps" in err and not out.exists()
    assert main(["export", str(demo_with_truth), "--xromm", str(tmp_path / "x.csv")]) == 0  # needs no time
    capsys.readouterr()
    for bad in ("0", "-3", "fast", "nan"):
        assert main(["export", str(demo_with_truth), "--mot", str(tmp_path / "k.mot"), "--fps", bad]) == 2
        assert "--fps" in one_error_line(capsys)


def anatomical_frames(poses_csv) -> dict[str, np.ndarray]:
    frames = {}
    for line in poses_csv.read_text().splitlines():
        if line.startswith("#") and "anatomical frame (" in line:
            component = line.lstrip("# ").split()[0]
            frames[component] = np.array(json.loads(line[line.index("[["):]))
    return frames


def csv_rows(path) -> list[dict]:
    return list(csv.DictReader(line for line in path.read_text().splitlines() if not line.startswith("#")))


def test_read_back_errors_of_one_run(demo_with_truth, tmp_path, capsys):
    from tests.io.test_motion_files import parse_mot, read_c3d

    out = {name: tmp_path / name for name in ("p.csv", "k.csv", "m.c3d", "k.mot", "m.trc", "x.csv")}
    assert main(["export", str(demo_with_truth), "--poses", str(out["p.csv"]), "--kinematics", str(out["k.csv"]),
                 "--c3d", str(out["m.c3d"]), "--mot", str(out["k.mot"]), "--trc", str(out["m.trc"]),
                 "--xromm", str(out["x.csv"]), "--fps", "30"]) == 0
    printed = capsys.readouterr().out
    assert all(f"wrote {path}" in printed for path in out.values())
    # C3D markers against the poses: each 4x4 of the poses CSV times its anatomical frame
    anatomical = anatomical_frames(out["p.csv"])
    expected = []
    for row in csv_rows(out["p.csv"]):
        markers = []
        for c in ("femoral", "tibial"):
            pose = np.array([float(row[f"{c}_m{r}{k}"]) for r in range(4) for k in range(4)]).reshape(4, 4)
            placed = pose @ anatomical[c]
            markers += [placed[:3, 3]] + [placed[:3, 3] + 10.0 * placed[:3, k] for k in range(3)]
        expected.append(markers)
    _, points, residual, info = read_c3d(out["m.c3d"])
    c3d_error = np.abs(points - np.array(expected)).max()
    assert info["rate"] == 30.0 and np.all(residual == 0)
    assert c3d_error < 3e-6, c3d_error  # measured 9.3e-7 mm: float32 storage of coordinates up to 30 mm
    # the .mot against the kinematics CSV
    _, columns, table = parse_mot(out["k.mot"])
    kinematics = np.array([[float(r[k]) for k in ("flexion_deg", "varus_deg", "internal_deg", "medial_mm",
                                                  "anterior_mm", "distraction_mm")] for r in csv_rows(out["k.csv"])])
    mot = table[:, 1:] * np.array([1, 1, 1, 1000, 1000, 1000])  # metres back to mm
    mot_error = np.abs(mot - kinematics).max()
    assert mot_error < 1e-7, mot_error  # measured 3.4e-8 mm (10 decimals of metres), 0 in degrees
    np.testing.assert_allclose(table[:, 0], np.array([0, 1, 2]) / 30.0)


def test_import_keeps_fps_or_the_videos_own(tmp_path, capsys):
    assert main(["demo", str(tmp_path / "d.fluoro"), "--frames", "3"]) == 0
    data = tmp_path / "d_data"
    videos = []
    for cam in ("cam1", "cam2"):
        frames = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in sorted((data / cam).iterdir())]
        height, width = frames[0].shape
        writer = cv2.VideoWriter(str(tmp_path / f"{cam}.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25, (width, height),
                                 isColor=False)
        for frame in frames:
            writer.write(frame)
        writer.release()
        videos.append(tmp_path / f"{cam}.avi")
    common = ["--camera", str(data / "calibration/cam1.json"), "--camera", str(data / "calibration/cam2.json"),
              "--images1", str(videos[0]), "--images2", str(videos[1]),
              "--model", f"femoral={data / 'models/femoral_component.stl'}",
              "--model", f"tibial={data / 'models/tibial_component.stl'}"]
    capsys.readouterr()
    assert main(["import", "--out", str(tmp_path / "v.fluoro"), *common]) == 0
    assert "25 frames per second" in capsys.readouterr().out
    time = load_project(tmp_path / "v.fluoro").settings["time"]
    assert time["fps"] == pytest.approx(25.0) and "cam1.avi (video)" in time["source"]
    assert main(["import", "--out", str(tmp_path / "v.fluoro"), "--force", "--fps", "30", *common]) == 0
    captured = capsys.readouterr()
    assert "--fps 30 kept although cam1.avi (video) says 25" in captured.err
    assert load_project(tmp_path / "v.fluoro").settings["time"] == {"fps": 30.0, "source": "user (--fps)"}
    assert main(["import", str(data), "--out", str(tmp_path / "png.fluoro")]) == 0  # PNGs say nothing
    captured = capsys.readouterr()
    assert "no frame rate (the images do not say; give --fps N" in captured.out and captured.err == ""
    assert "time" not in load_project(tmp_path / "png.fluoro").settings
    assert main(["import", str(data), "--out", str(tmp_path / "bad.fluoro"), "--fps", "-1"]) == 2
    assert "--fps" in one_error_line(capsys) and not (tmp_path / "bad.fluoro").exists()


def test_real_data_frames_keep_their_numbers_and_times(shared_data, tmp_path, capsys):
    """biplane-tka's pairs are frames 0, 20, 40, 50, …: C3D frames are evenly timed, so the
    command says so and the file keeps the true frame numbers and times."""
    from tests.io.test_motion_files import read_c3d

    project = tmp_path / "real.fluoro"
    assert main(["import", str(shared_data / "biplane-tka"), "--out", str(project), "--fps", "30"]) == 0
    frames = load_project(project).frames
    assert any(b - a != 1 for a, b in zip(frames, frames[1:]))
    capsys.readouterr()
    assert main(["export", str(project), "--c3d", str(tmp_path / "r.c3d"), "--trc", str(tmp_path / "r.trc")]) == 0
    assert "not consecutive" in capsys.readouterr().err
    _, points, residual, info = read_c3d(tmp_path / "r.c3d")
    assert len(points) == len(frames) and np.all(residual < 0)  # nothing matched yet: every marker invalid
    np.testing.assert_array_equal(info["frames"], frames)
    np.testing.assert_allclose(info["times"], np.array(frames) / 30.0, rtol=1e-6)
    lines = (tmp_path / "r.trc").read_text().splitlines()[6:]
    assert [line.split("\t")[0] for line in lines] == [str(f) for f in frames]
