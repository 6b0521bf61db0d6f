"""The motion exports of a session against values computed here, independently of the code
under test: anatomical markers from the demo's true poses (the rotation built with scipy
from the convention in docs/developer/conventions.rst), the C3D read back with the ``c3d`` package, the .mot against
the kinematics CSV of the same run, the .trc and XMALab CSV parsed as plain text; the time
base (kept, undoable, overridden, refused when absent)."""
from __future__ import annotations

import csv

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fluorogui.core.records import PoseRecord
from fluorogui.core.status import Status
from fluorogui.io.errors import InputError
from fluorogui.workflow import Session
from fluorogui.workflow.exports import (
    export_c3d,
    export_kinematics_csv,
    export_mot,
    export_trc,
    export_xromm,
    frame_rate,
    left_out_of_motion_files,
    set_frame_rate,
)

COMPONENTS = ("femoral", "tibial")


def independent_matrix(pose) -> np.ndarray:
    """docs/developer/conventions.rst: X = R m + t, R = Ry(beta) Rz(gamma) Rx(alpha), built with scipy
    (intrinsic Y-Z-X)."""
    x, y, z, alpha, beta, gamma = pose
    matrix = np.eye(4)
    matrix[:3, :3] = Rotation.from_euler("YZX", [beta, gamma, alpha], degrees=True).as_matrix()
    matrix[:3, 3] = x, y, z
    return matrix


def expected_markers(session, truth) -> np.ndarray:
    """frames × 8 markers × 3 (mm): origin and 10 mm along x, y, z of each anatomical frame."""
    out = []
    for frame in session.frames:
        row = []
        for c in COMPONENTS:
            placed = independent_matrix(truth[frame][c]) @ session.anatomical_frame(c)
            row += [placed[:3, 3]] + [placed[:3, 3] + 10.0 * placed[:3, k] for k in range(3)]
        out.append(row)
    return np.array(out)


def matched_truth(session, truth_of):
    truth = truth_of(session)
    for frame, by in truth.items():
        for c, pose in by.items():
            session.project.poses[(frame, c)] = PoseRecord(pose, status=Status.MATCHED)
    return truth


def read_kinematics_csv(path) -> dict[int, dict[str, float]]:
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    return {int(row["frame"]): row for row in csv.DictReader(lines)}


def test_c3d_markers_against_the_true_poses(demo, truth, tmp_path):
    from tests.io.test_motion_files import read_c3d

    session = Session.open(demo)
    truth = matched_truth(session, truth)
    set_frame_rate(session, 30.0)
    export_c3d(session, tmp_path / "m.c3d")
    labels, points, residual, info = read_c3d(tmp_path / "m.c3d")
    assert labels == [f"{c}_{p}" for c in COMPONENTS for p in ("origin", "x", "y", "z")]
    assert info["rate"] == 30.0 and len(points) == len(session.frames) and np.all(residual == 0)
    np.testing.assert_array_equal(info["frames"], session.frames)
    error = np.abs(points - expected_markers(session, truth)).max()
    assert error < 3e-6, error  # measured 9.3e-7 mm: float32 storage of coordinates up to 30 mm
    # the axis points lie 10 mm from the origin: the frames are rigid
    spans = np.linalg.norm(points.reshape(len(points), 2, 4, 3)[:, :, 1:] - points.reshape(len(points), 2, 4, 3)[
        :, :, :1], axis=3)
    np.testing.assert_allclose(spans, 10.0, atol=1e-4)


def test_mot_against_the_kinematics_csv_of_the_same_run(demo, truth, tmp_path):
    from tests.io.test_motion_files import parse_mot

    session = Session.open(demo)
    matched_truth(session, truth)
    set_frame_rate(session, 25.0)
    rows = session.knee_rows()
    export_kinematics_csv(session, tmp_path / "k.csv", rows)
    export_mot(session, tmp_path / "k.mot", rows=rows)
    header, columns, table = parse_mot(tmp_path / "k.mot")
    assert columns == ["time", "knee_flexion", "knee_varus", "knee_internal_rotation", "knee_medial_translation",
                       "knee_anterior_translation", "knee_distraction"]
    assert "inDegrees=yes" in header and any("meters" in line for line in header)
    kinematics = read_kinematics_csv(tmp_path / "k.csv")
    np.testing.assert_allclose(table[:, 0], np.array(session.frames) / 25.0)
    csv_values = np.array([[float(kinematics[f][k]) for k in ("flexion_deg", "varus_deg", "internal_deg",
                                                               "medial_mm", "anterior_mm", "distraction_mm")]
                           for f in session.frames])
    angles = np.abs(table[:, 1:4] - csv_values[:, :3]).max()
    translations = np.abs(table[:, 4:] * 1000.0 - csv_values[:, 3:]).max()
    assert angles < 1e-9 and translations < 1e-7, (angles, translations)  # measured 0 deg, 3.4e-8 mm


def test_trc_and_xromm_against_the_true_poses(demo, truth, tmp_path):
    session = Session.open(demo)
    truth = matched_truth(session, truth)
    set_frame_rate(session, 50.0)
    export_trc(session, tmp_path / "m.trc")
    lines = (tmp_path / "m.trc").read_text().splitlines()
    assert lines[2].split("\t")[:5] == ["50", "50", str(len(session.frames)), "8", "mm"]
    table = np.array([[float(v) for v in line.split("\t")] for line in lines[6:]])
    np.testing.assert_array_equal(table[:, 0], session.frames)
    np.testing.assert_allclose(table[:, 1], np.array(session.frames) / 50.0)
    error = np.abs(table[:, 2:].reshape(-1, 8, 3) - expected_markers(session, truth)).max()
    assert error < 1e-9, error  # measured 4.9e-11 mm: text with 10 decimals

    export_xromm(session, tmp_path / "x.csv")
    lines = (tmp_path / "x.csv").read_text().splitlines()
    numbers = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    for i, frame in enumerate(session.frames):
        for k, c in enumerate(COMPONENTS):
            matrix = numbers[i, 16 * k:16 * (k + 1)].reshape(4, 4, order="F")
            np.testing.assert_allclose(matrix, independent_matrix(truth[frame][c]), atol=1e-9)


def test_poses_not_matched_are_left_out_unless_asked(demo, truth, tmp_path):
    from tests.io.test_motion_files import parse_mot, read_c3d

    session = Session.open(demo)
    matched_truth(session, truth)
    set_frame_rate(session, 30.0)
    record = session.project.poses[(1, "tibial")]
    session.project.poses[(1, "tibial")] = PoseRecord(record.pose, status=Status.NEEDS_REVIEW, reason="too far")
    session.project.poses[(2, "femoral")] = PoseRecord(session.project.poses[(2, "femoral")].pose)  # placed
    del session.project.poses[(3, "tibial")]
    assert left_out_of_motion_files(session) == [(1, "tibial", "too far"), (2, "femoral", "placed")]
    for include in (False, True):
        export_c3d(session, tmp_path / "m.c3d", include_unreviewed=include)
        export_mot(session, tmp_path / "k.mot", include_unreviewed=include)
        export_xromm(session, tmp_path / "x.csv", include_unreviewed=include)
        _, points, residual, _ = read_c3d(tmp_path / "m.c3d")
        invalid = residual < 0
        assert invalid[1, 4:].all() != include and invalid[2, :4].all() != include
        assert invalid[3, 4:].all() and not invalid[0].any() and not invalid[1, :4].any()
        _, _, table = parse_mot(tmp_path / "k.mot")
        assert np.isnan(table[1:3, 1:]).all() != include and np.isnan(table[3, 1:]).all()
        assert np.isfinite(table[0]).all()
        rows = [line.split(",") for line in (tmp_path / "x.csv").read_text().splitlines()[1:]]
        assert (rows[1][16] == "NaN") != include and rows[3][16] == "NaN" and rows[1][0] != "NaN"


def test_the_frame_rate_is_kept_undoable_overridable_and_required(demo, truth, tmp_path):
    session = Session.open(demo)
    matched_truth(session, truth)
    assert frame_rate(session) is None
    for export in (export_c3d, export_trc, export_mot):
        with pytest.raises(InputError) as caught:
            export(session, tmp_path / f"m.{export.__name__[7:]}")
        assert str(tmp_path / "m.") in str(caught.value) and "frame rate" in str(caught.value)
        assert "\n" not in str(caught.value)
    assert not list(tmp_path.glob("m.*"))
    export_mot(session, tmp_path / "k.mot", fps=10.0)  # an override needs nothing stored
    assert "0.1\t" in (tmp_path / "k.mot").read_text() and frame_rate(session) is None
    set_frame_rate(session, 60.0)
    assert frame_rate(session) == 60.0 and session.history.can_undo()
    session.history.undo()
    assert frame_rate(session) is None
    session.history.redo()
    with pytest.raises(InputError, match="frame rate"):
        set_frame_rate(session, -1)
    session.save()
    assert frame_rate(Session.open(demo)) == 60.0
