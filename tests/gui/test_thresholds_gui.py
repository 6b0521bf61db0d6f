"""The app judges a match by the project's quality thresholds (issue 44, item 3; the
command line and Session: tests/workflow/test_thresholds.py)."""
from fluorogui.core.status import Status


def _match(window, qtbot):
    with qtbot.waitSignal(window.runner.finished, timeout=300000):
        assert window.run_match()


def test_the_app_flags_a_pose_by_the_projects_thresholds_and_matches_it_by_looser_ones(window, demo, qtbot):
    window.open_project(demo)
    c, s = window.controller, window.controller.session
    settings = s.settings
    settings.quality.max_sd_mm = settings.quality.max_sd_deg = 1e-9
    s.set_settings(settings)
    _match(window, qtbot)
    record = s.pose_record(c.component, c.frame)
    assert record.status == Status.NEEDS_REVIEW and "max_sd_mm" in record.reason
    assert "needs review" in window.statusBar().currentMessage() and "max_sd_mm" in window.statusBar().currentMessage()
    settings.quality.max_sd_mm = settings.quality.max_sd_deg = 2.0
    s.set_settings(settings)
    _match(window, qtbot)
    assert s.pose_record(c.component, c.frame).status == Status.MATCHED
