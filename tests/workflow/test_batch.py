"""Batch tracking on a Dask LocalCluster of two worker processes, including a worker that
dies in the middle of a project: only the frame in progress is lost, and it is retried."""
from __future__ import annotations

import os
import shutil

import pytest

from fluorogui.cli import main
from fluorogui.io.project.document import load_project
from fluorogui.workflow.batch import run_batch, summary_table


@pytest.mark.slow
def test_batch_tracks_projects_and_survives_a_dying_worker(demo, tmp_path, capsys):
    second = tmp_path / "second"
    shutil.copytree(demo.parent, second)
    other = second / demo.name
    marker = tmp_path / "crashed-once"
    broken = tmp_path / "broken.fluoro"
    broken.write_text("{ not json")

    def die_once_after_frame_1(path, frame, _marker=str(marker), _target=str(demo)):
        # the worker process is killed right after frame 1 of the first project is saved
        if path == _target and frame == 1 and not os.path.exists(_marker):
            open(_marker, "w").close()
            os._exit(1)

    rows = {r.project: r for r in run_batch([demo, other, broken], workers=2, frames="1:3",
                                            on_frame=die_once_after_frame_1)}
    assert marker.exists()  # the worker did die
    first = rows[str(demo)]
    assert first.ok and first.frames == 3
    # the retried task kept frame 1 (stored by the dead worker's run) and matched frames 2-3
    assert (first.kept, first.matched) == (2, 4), first
    assert rows[str(other)].ok and rows[str(other)].matched == 6 and rows[str(other)].kept == 0
    assert not rows[str(broken)].ok and "not valid JSON" in rows[str(broken)].error
    for path in (demo, other):
        project = load_project(path)
        assert all(project.poses[(f, c)].status == "matched" for f in (1, 2, 3) for c in ("femoral", "tibial"))
        assert not (path.parent / (path.name + ".lock")).exists()
    table = summary_table(list(rows.values()))
    assert "broken.fluoro" in table and "not valid JSON" in table


@pytest.mark.slow
def test_batch_command_prints_a_summary_and_exit_status(demo, capsys):
    assert main(["batch", str(demo), "--workers", "1", "--frames", "1:1", "--component", "tibial"]) == 0
    out = capsys.readouterr().out
    assert "project" in out.splitlines()[0] and str(demo)[-30:] in out
    assert main(["batch", str(demo), "--workers", "0"]) == 2


@pytest.mark.slow
def test_batch_skips_a_project_open_elsewhere_and_says_who_holds_it(demo):
    from fluorogui.io.project.lock import ProjectLock

    with ProjectLock(demo, "fluorogui (desktop)"):  # this test process plays the desktop app
        rows = list(run_batch([demo], workers=1, frames="1:1"))
    assert len(rows) == 1 and not rows[0].ok
    assert "in use by fluorogui (desktop)" in rows[0].error and str(os.getpid()) in rows[0].error
    assert (1, "femoral") not in load_project(demo).poses  # nothing written
