"""A single-plane session in the app: Match works from the default start and says which
direction is weak; Find implants (two views needed) says so instead of failing."""
from __future__ import annotations

import pytest

pytest.importorskip("pytestqt")

from fluorogui.io.importer import import_folder  # noqa: E402
from fluorogui.io.project.document import save_project  # noqa: E402
from fluorogui.workflow.messages import SINGLE_PLANE_NOTE  # noqa: E402


@pytest.mark.slow
def test_single_plane_match_in_the_app(window, shared_data, tmp_path, qtbot, dialogs, demo):
    path = tmp_path / "single.fluoro"
    save_project(import_folder(shared_data / "single-plane-tka"), path)
    window.open_project(path)
    session = window.controller.session
    assert session.n_views == 1
    # one image panel, not an empty second one still asking to open a session
    assert not window.panels[1].isVisibleTo(window) and window.panels[0].isVisibleTo(window)
    with qtbot.waitSignal(window.runner.finished, timeout=120000):
        assert window.run_match()
    record = session.pose_record(window.controller.component, window.controller.frame)
    assert record is not None and record.status == "matched"
    assert SINGLE_PLANE_NOTE in window.matcher.summary.text()
    assert not window.find_implants()
    assert "two views" in dialogs["warning"][-1][2]
    window.open_project(demo)  # a biplane session: both panels again
    assert window.panels[1].isVisibleTo(window) and window.panels[0].isVisibleTo(window)
