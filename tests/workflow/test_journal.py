"""A tracking run saves each frame by appending it to the project's journal, not by
rewriting the project: reopening the project (after a kill) has every frame stored so far,
a full save folds the journal in and deletes it, and a journal of another file or a line
cut short is left out."""
import json

import pytest

from fluorogui.io.project.journal import journal_path
from fluorogui.workflow import Session


def test_a_run_journals_its_frames_and_a_reopened_project_has_them(demo):
    session = Session.open(demo)
    before = demo.read_bytes()
    run = session.track(first=1, last=3, components="tibial", autosave=True)
    first = [next(run)]  # frame 1 stored, then the run is killed
    run.close()
    assert demo.read_bytes() == before  # the project itself was not rewritten
    assert journal_path(demo).exists()
    reopened = Session.open(demo)
    record = reopened.pose_record("tibial", 1)
    assert record is not None and record.status == first[0].status
    assert (record.pose == session.pose_record("tibial", 1).pose).all()
    assert reopened.rim_models() == session.rim_models()  # the settings came along


@pytest.mark.slow
def test_a_whole_run_ends_with_a_full_save_and_no_journal(demo):
    session = Session.open(demo)
    results = list(session.track(first=1, last=3, autosave=True))
    assert not journal_path(demo).exists()
    reopened = Session.open(demo)
    for r in results:
        assert (reopened.pose_record(r.component, r.frame).pose == r.pose).all()


def test_a_journal_of_another_file_or_cut_short_is_left_out(demo):
    session = Session.open(demo)
    run = session.track(first=1, last=2, components="tibial", autosave=True)
    next(run)
    run.close()
    lines = journal_path(demo).read_text().splitlines()
    entry = json.loads(lines[0])
    entry["stamp"] = "0" * 32  # written over another file
    journal_path(demo).write_text(json.dumps(entry) + "\n" + lines[0][: len(lines[0]) // 2])  # and one cut short
    reopened = Session.open(demo)
    assert reopened.pose_record("tibial", 1) == Session.open(demo).pose_record("tibial", 1)
    assert reopened.pose_record("tibial", 1) is None or reopened.pose_record("tibial", 1).match is None
