"""One verdict, with the project's thresholds (issue 44, item 3): the limits stored in the
project (or given on the command line) judge every match, through the same path in
``Session``, ``fluorogui match``, ``fluorogui track`` and the app (tests/gui/test_thresholds_gui.py).
Before, the matcher's own checks used the defaults whatever the project said: with both
SD limits at 1e-9 the demo's femur came back matched with an SD of 0.05 mm."""
from __future__ import annotations

import json

import pytest

from fluorogui.cli import main
from fluorogui.core.matching.quality import QualityThresholds
from fluorogui.core.status import Status
from fluorogui.workflow import Session

STRICT = {"max_sd_mm": 1e-9, "max_sd_deg": 1e-9}


def _with_quality(session: Session, **limits) -> None:
    settings = session.settings
    for name, value in limits.items():
        setattr(settings.quality, name, value)
    session.set_settings(settings)


def test_stricter_thresholds_flag_a_matched_pose_and_looser_ones_match_it_again(demo):
    session = Session.open(demo)
    _with_quality(session, **STRICT)
    strict, = session.match(0, "femoral")
    assert strict.status == Status.NEEDS_REVIEW
    assert "max_sd_mm" in strict.reason and "max_sd_deg" in strict.reason, strict.reason
    assert strict.failed == ["uncertainty"]
    assert strict.attempts == 1  # the SDs belong to the outlines: no other start is tried
    _with_quality(session, max_sd_mm=2.0, max_sd_deg=2.0)
    loose, = session.match(0, "femoral")
    assert loose.status == Status.MATCHED and loose.reason == ""


def test_track_judges_by_the_projects_thresholds(demo):
    session = Session.open(demo)
    _with_quality(session, min_edge_support=1.0, min_outline_support=1.0)  # every point on an edge: too strict
    results = list(session.track([1], "femoral", redo=True))
    assert [r.status for r in results] == [Status.NEEDS_REVIEW], [r.reason for r in results]
    assert "outline lies on" in results[0].reason


def test_track_on_the_command_line_takes_and_keeps_quality_options(demo, capsys):
    code = main(["track", str(demo), "--frames", "1", "--component", "femoral", "--json",
                 *[arg for name, value in STRICT.items() for arg in ("--quality", f"{name}={value}")]])
    out, err = capsys.readouterr()
    assert code == 3
    row = json.loads(out.splitlines()[0])
    assert row["status"] == "needs_review" and "max_sd_mm" in row["reason"]
    assert "max_sd_mm" in err  # the flagged frame's line
    assert Session.open(demo).settings.quality.max_sd_mm == 1e-9  # kept: a resumed run judges alike


def test_match_on_the_command_line_takes_quality_options(demo, capsys):
    session = Session.open(demo)
    args = ["match", "--model", str(session.project.model("femoral").mesh_path), "--json",
            "--start", *[str(v) for v in session.pose("femoral", 0)]]
    for k in range(session.n_views):
        args += ["--camera", str(_calibration(session, demo, k)), "--image", str(session.image_paths(0)[k])]
    assert main(args) == 0
    assert json.loads(capsys.readouterr().out)["status"] == "matched"
    assert main(args + ["--quality", "max_sd_mm=1e-9"]) == 3
    out = json.loads(capsys.readouterr().out)
    assert out["status"] == "needs_review" and "max_sd_mm" in out["reason"] and not out["converged"]


def _calibration(session, demo, k):
    from fluorogui.io.calibration import save_view_json

    path = demo.parent / f"view{k}.json"
    save_view_json(session.views[k], path)
    return path


@pytest.mark.parametrize("option, words", [("bogus=1", "NAME one of"), ("max_sd_mm=abc", "not a number"),
                                           ("min_edge_support=1.5", "a share"), ("max_sd_mm", "NAME=VALUE")])
def test_a_bad_quality_option_is_a_usage_error_naming_it(demo, capsys, option, words):
    assert main(["track", str(demo), "--frames", "1", "--quality", option]) == 2
    err = capsys.readouterr().err
    assert "--quality" in err and words in err and len(err.strip().splitlines()) == 1, err


def test_thresholds_out_of_range_are_refused_naming_them():
    with pytest.raises(ValueError, match="max_sd_mm"):
        QualityThresholds(max_sd_mm=-1.0)
    with pytest.raises(ValueError, match="min_visible_share"):
        QualityThresholds.from_dict({"min_visible_share": 2.0})
