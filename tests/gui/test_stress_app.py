"""The desktop app through repeated *Track both* runs on real frames, the Kinematics dock
redrawing as frames arrive (issue 44, item 1). The app once aborted in such a run
("none_dealloc": PySide6 6.12.0 lost a reference to None on every Qt call). Between runs
the counts of None, True and False wander with the data the runs leave, so what is checked
is the GUI thread's own work on what is there: showing every frame and redrawing the
kinematics again and again must give back every reference it takes. The long version is
``benchmarks/stress_app.py`` (50 runs of the 33 pairs)."""
import gc
import sys

import pytest

pytestmark = pytest.mark.slow

#: real pairs tracked per run (frames 0, 20, 40, 50, 60)
FRAMES = 5
RUNS = 2
#: times the GUI thread shows every frame and redraws the kinematics afterwards
BROWSES = 10
#: references the counts may lose over those (measured: 0 with PySide6 6.11.3; 6.12.0 lost 8,350 to None
#: and 200 to True)
LOSS_LIMIT = 50


def _counts():
    gc.collect()  # (cycles awaiting collection hold references too)
    return sys.getrefcount(None), sys.getrefcount(True), sys.getrefcount(False)


def test_tracking_again_and_again_and_browsing_keeps_the_reference_counts(window, qtbot, shared_data):
    from fluorogui.io.importer import import_folder

    project = import_folder(shared_data / "biplane-tka")
    project.frames = project.frames[:FRAMES]
    window.controller.set_project(project, None)
    window.show()
    window.knee_dock.show()
    window.knee_dock.raise_()
    window.controller.set_frame(project.frames[0])
    assert window.tasks.find_implants()
    qtbot.waitUntil(lambda: not window.runner.is_running(), timeout=120_000)
    for _ in range(RUNS):
        window.controller.set_frame(project.frames[0])
        assert window.tasks.track_both()
        qtbot.waitUntil(lambda: not window.runner.is_running(), timeout=300_000)
        track = window.tasks.last_track  # (frame 0 again only while it is not matched)
        assert track.done == len(track.frames) >= FRAMES - 1 and len(track.matched) >= FRAMES - 2
    # what the GUI thread did between the tracked frames, again and again on the same data:
    # a sound binding gives back every reference it takes
    def browse():
        for frame in project.frames:
            window.controller.set_frame(frame)
        window.knee_panel.redraw()

    browse()
    before = _counts()
    for _ in range(BROWSES):
        browse()
    after = _counts()
    assert all(a > b - LOSS_LIMIT for a, b in zip(after, before)), (before, after)
