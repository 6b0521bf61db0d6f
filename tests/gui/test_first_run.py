"""First run and errors: the guided tour (once), the crash handler's report, and starting
with a project path that is missing, unreadable or a folder."""
import os
import sys

import pytest

pytest.importorskip("pytestqt")
from PySide6.QtCore import QPoint, QRect  # noqa: E402
from PySide6.QtWidgets import QApplication  # noqa: E402

from fluorogui.gui.app import open_start_path  # noqa: E402
from fluorogui.gui.dialogs.tour import STEPS, start_tour  # noqa: E402


def test_tour_shows_once_and_steps_through(window):
    tour = start_tour(window)
    assert tour is not None and tour.isVisible() and "1 of" in tour.title.text()
    for _ in range(len(STEPS) - 1):
        tour.next_button.click()
    assert tour.next_button.text() == "Done" and tour.back_button.isEnabled()
    assert f"{len(STEPS)} of {len(STEPS)}" in tour.title.text()
    tour.next_button.click()
    assert not tour.isVisible()
    assert start_tour(window) is None  # remembered: not again
    again = start_tour(window, force=True)  # Help → Guided tour
    assert again is not None
    again.close()


def _global_rect(widget):
    return QRect(widget.mapToGlobal(QPoint(0, 0)), widget.size())


def test_the_tour_box_fits_its_text_and_leaves_what_it_describes_in_view(window, demo, qtbot):
    window.open_project(demo)
    window.setGeometry(0, 0, 800, 760)  # the test screen is 800×800
    window.show()
    qtbot.waitExposed(window)
    m = window.matcher
    described = {"Place": [m.place_button], "Match": [m.run_button, m.run_both_button, m.plot],
                 "Accept and track": [m.accept_button, m.track_button, m.track_both_button, window.timeline]}
    tour = start_tour(window, force=True)
    qtbot.waitExposed(tour)
    seen = set()
    for step in range(len(STEPS)):
        tour.show_step(step)
        title = STEPS[step][0]
        text = tour.text
        assert text.heightForWidth(text.width()) <= text.height(), title  # every line of the text in the box
        assert tour.title.sizeHint().width() <= tour.title.width()
        box = tour.frameGeometry()
        assert window.screen().availableGeometry().contains(box)
        for widget in described.get(title, []):
            assert not box.intersects(_global_rect(widget)), (title, widget)
        if title == "The two views":  # on 800 px the box cannot miss both views: it leaves the implants in view
            for panel in window.panels:
                view = _global_rect(panel)
                assert not box.contains(view.center())
                covered = box.intersected(view)
                assert covered.width() * covered.height() < 0.25 * view.width() * view.height()
        seen.add(title)
    assert set(described) | {"The two views"} <= seen
    tour.close()


def _stop_logging():
    import logging

    root = logging.getLogger()
    for handler in [h for h in root.handlers if getattr(h, "_fluorogui", False)]:
        root.removeHandler(handler)
        handler.close()
    logging.captureWarnings(False)


def test_crash_report_logs_autosaves_and_copies(window, demo, tmp_path, monkeypatch, request):
    from fluorogui.gui.dialogs.crash import crash_dialog, crash_report
    from fluorogui.logs import log_file_path, setup_logging

    monkeypatch.setenv("FLUOROGUI_DATA_DIR", str(tmp_path / "data"))
    setup_logging()
    request.addfinalizer(_stop_logging)
    window.open_project(demo)
    window.review.step_frame(1)
    window.controller.session.set_reviewed(window.controller.component, 1, True)  # unsaved work
    try:
        raise RuntimeError("boom in a slot")
    except RuntimeError:
        report = crash_report(window, *sys.exc_info())
    assert report["summary"] == "RuntimeError: boom in a slot"
    assert report["autosave"] is not None and report["autosave"].exists()
    assert "boom in a slot" in log_file_path().read_text() and "Traceback" in log_file_path().read_text()
    box = crash_dialog(window, report)
    assert str(report["autosave"]) in box.informativeText() and str(report["log"]) in box.informativeText()
    box.copy_button.click()
    assert "RuntimeError: boom in a slot" in QApplication.clipboard().text()
    box.close()


def test_start_with_a_missing_path_says_so_and_keeps_the_window(window, dialogs, tmp_path):
    assert not open_start_path(window, tmp_path / "nowhere.fluoro")
    assert "no such file" in dialogs["warning"][-1][2]
    assert "File → Open" in window.panels[0].placeholder  # the window still says what to do


def test_start_with_a_folder_named_like_a_project(window, dialogs, tmp_path):
    folder = tmp_path / "odd.fluoro"
    folder.mkdir()
    assert not open_start_path(window, folder)
    assert str(folder) in dialogs["warning"][-1][2] or "folder" in dialogs["warning"][-1][2].lower()


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads every file")
def test_start_with_an_unreadable_project(window, dialogs, demo):
    demo.chmod(0)
    assert not open_start_path(window, demo)
    assert "not readable" in dialogs["warning"][-1][2]


def test_start_with_a_folder_fills_the_import_dialog(window, monkeypatch, tmp_path):
    seen = []
    monkeypatch.setattr(window.files, "import_session", lambda fill=None, folder=None: seen.append(folder))
    assert open_start_path(window, tmp_path)
    assert seen == [tmp_path]


def test_a_folder_argument_starts_the_app_not_a_sub_command(tmp_path):
    from fluorogui.__main__ import _is_project_file_argument

    assert _is_project_file_argument([str(tmp_path)])
    assert not _is_project_file_argument(["match"])
    assert not _is_project_file_argument(["--version"])


def test_a_missing_model_clears_its_overlay_and_offers_locate(window, demo, monkeypatch, qtbot):
    from PySide6.QtWidgets import QFileDialog

    window.open_project(demo)  # a first project: its femoral overlay is on screen
    assert window.panels[0].model_outline("femoral") is not None
    mesh = demo.parent / "models" / "femoral_component.stl"
    moved = demo.parent / "moved_femoral.stl"
    mesh.rename(moved)
    asked = []

    def ask(box):
        asked.append(box.text())
        return next(b for b in box.buttons() if b.text() == "Locate…")

    monkeypatch.setattr(window.missing, "ask", ask)
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (str(moved), ""))
    window.controller.session.history.set_clean()
    window.open_project(demo, ask=False)  # the same project again, now with its femoral mesh missing
    assert all(panel.model_outline("femoral") is None for panel in window.panels)  # no stale overlay
    qtbot.waitUntil(lambda: bool(asked))
    assert "femoral_component.stl" in asked[0] and "Locate" in asked[0]
    # Locate… relinked it: the model and its overlay are back, as one undoable step
    assert window.session.project.model("femoral").mesh_path == moved
    assert window.panels[0].model_outline("femoral") is not None
    window.edit.undo_action.trigger()
    assert window.session.project.model("femoral").mesh_path.name == "femoral_component.stl"
    assert window.panels[0].model_outline("femoral") is None


def test_match_with_a_missing_model_offers_locate_not_a_repeat(window, demo, monkeypatch):
    window.open_project(demo)
    offered = []
    monkeypatch.setattr(window.missing, "offer_locate", lambda name, error: offered.append((name, str(error))))
    (demo.parent / "models" / "tibial_component.stl").unlink()
    window.controller.session.cache.forget_mesh("tibial")
    window.controller.set_component("tibial")
    assert not window.run_match()
    assert offered and offered[0][0] == "tibial" and "tibial_component.stl" in offered[0][1]
