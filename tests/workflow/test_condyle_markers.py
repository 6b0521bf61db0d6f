"""The condyles' contact points as C3D / .trc markers (``--condyles``): read back (the C3D by
another library), taken into the tray's anatomical frame with an independent pose matrix,
they are the contact CSV's points; frames left out of motion files are invalid markers."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from fluorogui.core.records import PoseRecord
from fluorogui.io.errors import InputError
from fluorogui.workflow import Session
from fluorogui.workflow.contact import export_contact_csv
from fluorogui.workflow.exports import set_frame_rate
from fluorogui.workflow.exports.formats.condyles import CONDYLE_MARKERS, FORMAT, export_condyle_markers
from fluorogui.workflow.exports.registry import ExportOptions, write_exports
from tests.workflow.test_motion_exports import independent_matrix, matched_truth


def csv_points(path) -> dict[int, np.ndarray]:
    """frame -> 2 × 3 (medial, lateral) of the contact CSV (tibial anatomical frame)."""
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    return {int(r["frame"]): np.array([[float(r[f"{n}_{a}_mm"]) for a in "xyz"] for n in ("medial", "lateral")])
            for r in csv.DictReader(lines)}


def in_tray_frame(session, truth, frame, world):
    """World points into the tibial anatomical frame, through an independent pose matrix."""
    to_world = independent_matrix(truth[frame]["tibial"]) @ session.anatomical_frame("tibial")
    back = np.linalg.inv(to_world)
    return world @ back[:3, :3].T + back[:3, 3]


def test_c3d_and_trc_hold_the_contact_csvs_points_in_world(demo, truth, tmp_path):
    from tests.io.test_motion_files import read_c3d

    session = Session.open(demo)
    truth = matched_truth(session, truth)
    set_frame_rate(session, 30.0)
    expected = csv_points(export_contact_csv(session, tmp_path / "contact.csv"))
    export_condyle_markers(session, tmp_path / "c.c3d")
    labels, points, residual, info = read_c3d(tmp_path / "c.c3d")
    assert labels == list(CONDYLE_MARKERS) and info["rate"] == 30.0 and info["units"] == "mm"
    np.testing.assert_array_equal(info["frames"], session.frames)
    assert np.all(residual == 0) and "medial femoral condyle" in info["descriptions"][0]
    for i, frame in enumerate(session.frames):
        got = in_tray_frame(session, truth, frame, points[i])
        assert np.abs(got - expected[frame]).max() < 3e-6  # measured 7.7e-7 mm: float32 in the C3D

    export_condyle_markers(session, tmp_path / "c.trc")
    lines = (tmp_path / "c.trc").read_text().splitlines()
    assert lines[2].split("\t")[:5] == ["30", "30", str(len(session.frames)), "2", "mm"]
    assert lines[3].split("\t")[2::3][:2] == list(CONDYLE_MARKERS)
    table = np.array([[float(v) for v in line.split("\t")] for line in lines[6:]])
    np.testing.assert_array_equal(table[:, 0], session.frames)
    np.testing.assert_allclose(table[:, 1], np.array(session.frames) / 30.0)
    for i, frame in enumerate(session.frames):
        got = in_tray_frame(session, truth, frame, table[i, 2:].reshape(2, 3))
        assert np.abs(got - expected[frame]).max() < 1e-9  # measured 9.4e-11 mm: 10 decimals
    # the condyles are some 40 mm apart on the demo's femur, and both lie on the tray's side
    assert np.all(np.linalg.norm(table[:, 2:5] - table[:, 5:8], axis=1) > 20)


def test_a_tray_pose_not_matched_leaves_its_frame_out_unless_asked(demo, truth, tmp_path):
    session = Session.open(demo)
    truth = matched_truth(session, truth)
    set_frame_rate(session, 25.0)
    frame = session.frames[1]
    session.project.poses[(frame, "tibial")] = PoseRecord(truth[frame]["tibial"], status="placed")
    export_condyle_markers(session, tmp_path / "c.trc")
    rows = [line.split("\t") for line in (tmp_path / "c.trc").read_text().splitlines()[6:]]
    assert rows[1][2:] == [""] * 6 and all(cell for cell in rows[0][2:])
    export_condyle_markers(session, tmp_path / "all.trc", include_unreviewed=True)
    rows = [line.split("\t") for line in (tmp_path / "all.trc").read_text().splitlines()[6:]]
    assert all(cell for cell in rows[1][2:])


def test_the_registry_writes_it_and_refuses_other_suffixes(demo, truth, tmp_path):
    session = Session.open(demo)
    matched_truth(session, truth)
    assert FORMAT.wrong_suffix(tmp_path / "c.csv") == "the file must be .c3d or .trc (the suffix chooses the format)"
    assert FORMAT.wrong_suffix(tmp_path / "c.TRC") == ""
    with pytest.raises(InputError, match="frame rate"):
        write_exports(session, {"condyles": tmp_path / "c.trc"}, ExportOptions())
    written = write_exports(session, {"condyles": tmp_path / "c.trc"}, ExportOptions(fps=10.0))
    assert [p.name for p in written] == ["c.trc"]
