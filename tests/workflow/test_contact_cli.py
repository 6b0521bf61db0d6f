"""``fluorogui kinematics --contact / --pivot / --mean`` (issue 47's contract): sphere
condyles turning about a known vertical axis (the lowest points and the pivot known by
hand), a plane insert placed by its insert -> tray matrix, lift-off, trials averaged from
projects, and bad input as one line with exit 2."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import pyvista as pv
from scipy.spatial.transform import Rotation

from fluorogui.cli import main
from fluorogui.core.projection.pose import matrix_to_pose, pose_to_matrix

RADII = {"medial": 20.0, "lateral": 22.0}
CENTRES = {"medial": np.array([-22.0, 1.0, 0.0]), "lateral": np.array([23.0, -1.0, 1.0])}  # right knee
AXIS = CENTRES["medial"] + 0.25 * (CENTRES["lateral"] - CENTRES["medial"])  # a medial pivot


def motion(count=19):
    """Femoral poses (tibia at the identity): lifted 25 mm, flexed 0-120 deg about the line
    through the sphere centres, turned +/-15 deg about the vertical axis through AXIS."""
    line = CENTRES["lateral"] - CENTRES["medial"]
    out = []
    for k in range(count):
        flex = np.eye(4)
        flex[:3, :3] = Rotation.from_rotvec(np.radians(120 * k / (count - 1)) * line / np.linalg.norm(line)).as_matrix()
        flex[:3, 3] = CENTRES["medial"] - flex[:3, :3] @ CENTRES["medial"]
        turn = np.eye(4)
        turn[:3, :3] = Rotation.from_euler("z", 15 * np.sin(k / 2.0), degrees=True).as_matrix()
        turn[:3, 3] = AXIS - turn[:3, :3] @ AXIS
        out.append(turn @ pose_to_matrix([0, 0, 25, 0, 0, 0]) @ flex)
    return out


@pytest.fixture
def files(tmp_path):
    spheres = [pv.Sphere(radius=RADII[n], center=CENTRES[n], theta_resolution=120, phi_resolution=60)
               for n in ("medial", "lateral")]
    (spheres[0] + spheres[1]).save(tmp_path / "condyles.stl")
    pv.Plane(i_size=150, j_size=150).triangulate().save(tmp_path / "insert.stl")  # z = 0, facing up
    eye = tmp_path / "eye.json"
    eye.write_text(json.dumps({"matrix": np.eye(4).tolist()}))
    lifted = np.eye(4)
    lifted[2, 3] = 2.0
    (tmp_path / "up2.json").write_text(json.dumps({"matrix": lifted.tolist()}))
    rows = ["frame,component,x,y,z,alpha,beta,gamma"]
    for k, pose in enumerate(motion()):
        rows += [f"{10 * k},femoral," + ",".join(f"{v:.12f}" for v in matrix_to_pose(pose)),
                 f"{10 * k},tibial,0,0,0,0,0,0"]
    rows.append("999,femoral,0,0,25,0,0,0")  # no tibia: NaN
    (tmp_path / "poses.csv").write_text("\n".join(rows) + "\n")
    return tmp_path


def kinematics(files, *extra):
    return main(["kinematics", "--poses", str(files / "poses.csv"), "--side", "right", "--femoral-mesh",
                 str(files / "condyles.stl"), "--femoral-frame", str(files / "eye.json"), "--tibial-frame",
                 str(files / "eye.json"), *extra])


def table(path):
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    return list(csv.DictReader(lines))


def test_contact_csv_and_pivot(files, capsys):
    code = kinematics(files, "--contact", str(files / "contact.csv"), "--pivot", "--plot", str(files / "c.png"),
                      "--liftoff-mm", "0.5")
    out, err = capsys.readouterr()
    assert code == 0, err
    pivot = json.loads(out)  # stdout is the one JSON line; what was written goes to stderr
    assert out.count("\n") == 1 and set(pivot) == {"x_mm", "y_mm", "kind", "frames_used"}
    # measured 0.0000 mm at the JSON's 4 decimals; the issue asks 0.5
    assert np.hypot(pivot["x_mm"] - AXIS[0], pivot["y_mm"] - AXIS[1]) < 0.001
    assert pivot["kind"] == "medial" and pivot["frames_used"] == 19
    assert "wrote" in err and "1 frame written as NaN" in err
    rows = table(files / "contact.csv")
    assert list(rows[0]) == ["frame", "medial_x_mm", "medial_y_mm", "medial_z_mm", "lateral_x_mm", "lateral_y_mm",
                             "lateral_z_mm", "medial_gap_mm", "lateral_gap_mm", "liftoff", "status"]
    for row, pose in zip(rows, motion()):
        for name in ("medial", "lateral"):
            want = (pose @ [*CENTRES[name], 1])[:3] - [0, 0, RADII[name]]
            got = [float(row[f"{name}_{a}_mm"]) for a in "xyz"]
            assert got == pytest.approx(want, abs=0.002)
        assert row["medial_gap_mm"] == row["lateral_gap_mm"] == "" and row["status"] == "matched"
        assert row["liftoff"] == "medial"  # no insert: heights 5 and 4 mm, 1 mm apart, beyond 0.5
    assert rows[-1]["frame"] == "999" and rows[-1]["status"] == "missing" and rows[-1]["medial_x_mm"] == "NaN"
    assert (files / "c.png").read_bytes()[:4] == b"\x89PNG"


def test_insert_frame_gaps_and_liftoff_threshold(files, capsys):
    code = kinematics(files, "--contact", str(files / "gaps.csv"), "--insert-mesh", str(files / "insert.stl"),
                      "--insert-frame", str(files / "up2.json"), "--liftoff-mm", "2.5")
    assert code == 0, capsys.readouterr().err
    rows = table(files / "gaps.csv")[:-1]
    for row in rows:  # the insert 2 mm above the tray: each gap is the height less 2 mm
        for name in ("medial", "lateral"):
            assert float(row[f"{name}_gap_mm"]) == pytest.approx(float(row[f"{name}_z_mm"]) - 2.0, abs=0.002)
        assert row["liftoff"] == "medial"  # medial gap 3 mm, lateral 2 mm: only the medial beyond 2.5
    assert "# lift-off threshold: 2.5 mm" in (files / "gaps.csv").read_text()


@pytest.mark.parametrize("extra, words", [
    (["--out", "OUT", "--insert-mesh", "INSERT"], "--insert-mesh goes with --contact or --pivot"),
    (["--contact", "OUT", "--insert-frame", "UP"], "--insert-frame places the --insert-mesh"),
    (["--normalize", "time", "--out", "OUT"], "--normalize goes with --mean"),
    (["--contact", "OUT", "--liftoff-mm", "0"], "out of range"),
    (["--contact", "OUT", "--plot", "OUT.txt"], "the figure must be .png, .svg or .pdf"),
    ([], "say what to write"),
])
def test_usage_mistakes_are_one_line(files, capsys, extra, words):
    names = {"INSERT": files / "insert.stl", "OUT": files / "x.csv", "UP": files / "up2.json"}
    code = kinematics(files, *(str(names.get(a, a)) for a in extra))
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and words in err, err
    assert not (files / "x.csv").exists()


def test_contact_needs_the_femoral_surface(files, capsys):
    code = main(["kinematics", "--poses", str(files / "poses.csv"), "--side", "right", "--femoral-frame",
                 str(files / "eye.json"), "--tibial-frame", str(files / "eye.json"), "--pivot"])
    assert code == 2 and "--contact and --pivot need --femoral-mesh" in capsys.readouterr().err
    half = pv.Sphere(radius=20, center=(30, 0, 0))  # all on the subject's right: no medial condyle
    half.save(files / "half.stl")
    code = main(["kinematics", "--poses", str(files / "poses.csv"), "--side", "right", "--femoral-mesh",
                 str(files / "half.stl"), "--femoral-frame", str(files / "eye.json"), "--tibial-frame",
                 str(files / "eye.json"), "--pivot"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "half.stl" in err and "no medial condyle" in err


def test_mean_of_two_projects(demo, truth, tmp_path, capsys):
    from fluorogui.core.records import PoseRecord
    from fluorogui.core.status import Status
    from fluorogui.workflow import Session

    session = Session.open(demo)
    for frame, by in truth(session).items():
        for component, pose in by.items():
            session.project.poses[(frame, component)] = PoseRecord(pose, status=Status.MATCHED)
    session.save()
    code = main(["kinematics", "--mean", str(demo), str(demo), "--normalize", "flexion", "--out",
                 str(tmp_path / "mean.csv"), "--plot", str(tmp_path / "mean.pdf")])
    out, err = capsys.readouterr()
    assert code == 0, err
    rows = table(tmp_path / "mean.csv")
    assert list(rows[0])[:5] == ["flexion_deg", "quantity", "n", "mean", "sd"]
    assert {r["quantity"] for r in rows} >= {"medial_y_mm", "lateral_y_mm", "varus_deg"}
    assert all(float(r["sd"]) == 0 and r["trial_1"] == r["trial_2"] == r["mean"] for r in rows)  # one trial twice
    assert (tmp_path / "mean.pdf").read_bytes()[:5] == b"%PDF-"
    code = main(["kinematics", "--mean", str(demo), "--out", str(tmp_path / "one.csv")])
    assert code == 2 and "--mean needs two projects or more" in capsys.readouterr().err
    code = main(["kinematics", "--mean", str(demo), str(tmp_path / "none.fluoro"), "--out", str(tmp_path / "m.csv")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "none.fluoro" in err
