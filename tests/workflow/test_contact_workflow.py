"""Contact kinematics of a session (``workflow.contact``), its CSV, the left knee through the
session's side, trials averaged from sessions (``workflow.trials``) and the figures
(``workflow.contact_plot``)."""
from __future__ import annotations

import csv

import numpy as np
import pytest
from matplotlib.figure import Figure

from fluorogui.core.knee.averaging import PERCENT, by_time
from fluorogui.core.records import PoseRecord
from fluorogui.core.status import Status
from fluorogui.workflow import Session
from fluorogui.workflow.contact import (
    CONTACT_COLUMNS,
    contact_rows,
    contact_world_points,
    export_contact_csv,
    pivot_of_rows,
    session_contact_job,
    session_contact_setup,
)
from fluorogui.workflow.contact_plot import draw_contact, save_contact_figure
from fluorogui.workflow.trials import Trial, average_trials, save_mean_plot, trial_of_session, write_mean_csv


def prepared(demo, truth) -> Session:
    """Frames 0 and 3 matched, 1 with its tibia needing review, 2 without a femoral pose."""
    session = Session.open(demo)
    for frame, by in truth(session).items():
        for component, pose in by.items():
            status = Status.NEEDS_REVIEW if (frame, component) == (1, "tibial") else Status.MATCHED
            session.project.poses[(frame, component)] = PoseRecord(pose, status=status, reason="residual high")
    session.project.poses.pop((2, "femoral"))
    return session


def read_contact(path):
    with open(path, newline="") as handle:
        lines = handle.read().splitlines()
    header = [line[2:] for line in lines if line.startswith("# ")]
    table = list(csv.reader(line for line in lines if not line.startswith("#")))
    return header, table[0], table[1:]


def test_rows_follow_the_kinematics_status_and_the_csv_round_trips(demo, truth, tmp_path):
    session = prepared(demo, truth)
    rows = {r.frame: r for r in contact_rows(session)}
    knee = {r.frame: r for r in session.knee_rows()}
    assert [rows[f].status for f in range(4)] == ["matched", "needs_review", "missing", "matched"]
    assert rows[1].reason == knee[1].reason and "tibial needs review" in rows[1].reason
    assert np.all(np.isnan(rows[2].contact.medial.lowest)) and rows[2].contact.liftoff == ""
    for f in (0, 1, 3):
        medial, lateral = rows[f].contact.medial.lowest, rows[f].contact.lateral.lowest
        assert np.all(np.isfinite(medial)) and medial[0] < 0 < lateral[0]  # right knee: + lateral
        assert rows[f].flexion_deg == pytest.approx(knee[f].values.flexion_deg, abs=1e-12)
    path = export_contact_csv(session, tmp_path / "contact.csv")
    header, columns, table = read_contact(path)
    assert tuple(columns) == CONTACT_COLUMNS
    # two matched frames (needing review is not enough): the pivot is their lines' intersection
    (m0, l0), (m3, l3) = ((rows[f].contact.medial.lowest[:2], rows[f].contact.lateral.lowest[:2]) for f in (0, 3))
    s, _ = np.linalg.solve(np.column_stack([l0 - m0, -(l3 - m3)]), m3 - m0)
    cross = m0 + s * (l0 - m0)
    found = pivot_of_rows(list(rows.values()))
    assert (found.frames_used, found.frames_ignored) == (2, 2)
    assert [found.x_mm, found.y_mm] == pytest.approx(cross, abs=1e-9)
    assert "side: right" in header and f"pivot: x {cross[0]:.2f} mm, y {cross[1]:.2f} mm" in "".join(header)
    assert "frame 2: NaN: no femoral pose" in header
    for line in table:
        row = rows[int(line[0])]
        want = [*row.contact.medial.lowest, *row.contact.lateral.lowest]
        np.testing.assert_allclose([float(v) for v in line[1:7]], want, atol=1e-9)
        assert line[7:9] == ["", ""] and line[10] == row.status  # no insert: gaps empty
        assert line[9] == row.contact.liftoff


def test_an_insert_on_a_flat_tray_gives_gaps_equal_to_the_heights(demo, truth, tmp_path):
    """The tray itself as the insert: under each condyle its top is the flat z = 0 of the
    tibial frame, so the closest point is the lowest point and the gap its height."""
    session = prepared(demo, truth)
    tray = session.raw_mesh("tibial")
    setup = session_contact_setup(session, insert_mesh=tray, liftoff_mm=0.5)
    rows = [r for r in contact_rows(session, setup) if r.status != "missing"]
    for row in rows:
        for name in ("medial", "lateral"):
            c = getattr(row.contact, name)
            assert c.gap_mm == pytest.approx(c.lowest[2], abs=0.01)
            np.testing.assert_allclose(c.femoral_point, c.lowest, atol=0.05)
    path = export_contact_csv(session, tmp_path / "gaps.csv", insert_mesh=tray, liftoff_mm=0.5, rows=rows)
    header, _, table = read_contact(path)
    assert "lift-off threshold: 0.5 mm" in header and all(line[7] and line[8] for line in table)


def test_a_left_knee_reads_the_mirror_of_the_right(demo, truth):
    """The same poses read as a left knee: the medial condyle is now the one on the
    subject's right, and x is mirrored so that + is still lateral."""
    session = prepared(demo, truth)
    right = {r.frame: r.contact for r in contact_rows(session)}
    session.set_side("left")
    left = {r.frame: r.contact for r in contact_rows(session)}
    for f in (0, 1, 3):
        np.testing.assert_allclose(left[f].medial.lowest, right[f].lateral.lowest * [-1, 1, 1], atol=1e-9)
        np.testing.assert_allclose(left[f].lateral.lowest, right[f].medial.lowest * [-1, 1, 1], atol=1e-9)


def test_world_points_are_the_same_points_on_either_side(demo, truth):
    """In world the lowest points do not depend on which knee it is: a left knee's medial
    point is where the right knee's lateral one is (the mirror undone)."""
    session = prepared(demo, truth)
    frame = session.anatomical_frame("tibial")
    world = {}
    for side in ("right", "left"):
        session.set_side(side)
        row = contact_rows(session, frames=[0])[0]
        world[side] = contact_world_points(row, session.pose("tibial", 0), frame, side)
    np.testing.assert_allclose(world["left"]["medial"], world["right"]["lateral"], atol=1e-9)
    np.testing.assert_allclose(world["left"]["lateral"], world["right"]["medial"], atol=1e-9)
    assert np.linalg.norm(world["right"]["medial"] - world["right"]["lateral"]) > 20  # two condyles apart


def test_a_contact_job_computes_from_what_it_took_then(demo, truth):
    """The job (the app runs it in a thread) gives the rows and pivot of the session as it was
    when the job was made, not as it is when it runs."""
    session = prepared(demo, truth)
    job = session_contact_job(session)
    expected = contact_rows(session)
    session.project.poses.clear()
    rows, found = job()
    assert [r.status for r in rows] == [r.status for r in expected]
    for got, want in zip(rows, expected):
        np.testing.assert_allclose(got.contact.medial.lowest, want.contact.medial.lowest, atol=1e-12)
    assert found.frames_used == pivot_of_rows(expected).frames_used


def test_trials_averaged_from_sessions(demo, truth, tmp_path):
    """A session's trial and a copy of it shifted to later frame numbers: by time the mean
    is the trial and the SD zero; only matched frames enter."""
    session = prepared(demo, truth)
    trial = trial_of_session(session, name="a")
    assert np.all(np.isnan(trial.values[[1, 2]])) and np.all(np.isfinite(trial.values[[0, 3]]))
    assert trial.quantities[:2] == ("flexion_deg", "varus_deg") and "medial_y_mm" in trial.quantities
    shifted = Trial("b", trial.frames * 3 + 40, trial.flexion, trial.quantities, trial.values)
    averaged = average_trials([trial, shifted], "time")
    np.testing.assert_allclose(averaged.curves.mean, by_time(trial.frames, trial.values), atol=1e-12)
    assert np.nanmax(averaged.curves.sd) == pytest.approx(0, abs=1e-12)
    assert np.all(averaged.curves.n == 2) and averaged.curves.x.tolist() == PERCENT.tolist()
    out = write_mean_csv(tmp_path / "mean.csv", averaged)
    _, columns, table = read_contact(out)
    assert columns == ["percent", "quantity", "n", "mean", "sd", "trial_1", "trial_2"]
    assert len(table) == len(PERCENT) * len(trial.quantities)
    plot = save_mean_plot(tmp_path / "mean.pdf", averaged)
    assert plot.read_bytes()[:5] == b"%PDF-"
    with pytest.raises(ValueError, match="two trials or more"):
        average_trials([trial], "time")


def test_the_contact_figure_draws_each_condyle_against_flexion(demo, truth, tmp_path):
    session = prepared(demo, truth)
    rows = contact_rows(session)
    figure = Figure()
    ap, tray = draw_contact(figure, rows)
    lines = {line.get_label(): line for line in ap.get_lines()}
    medial = lines["medial"]
    good = [r for r in rows if r.status == "matched"]  # needs-review frames are ringed, not joined
    np.testing.assert_allclose(medial.get_xdata(), [r.flexion_deg for r in good])
    np.testing.assert_allclose(medial.get_ydata(), [r.contact.medial.lowest[1] for r in good])
    save_contact_figure(rows, tmp_path / "contact.png")
    assert (tmp_path / "contact.png").read_bytes()[:4] == b"\x89PNG"
