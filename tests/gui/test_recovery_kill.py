"""A crash loses at most the frame in flight (issue 44, item 2): the app is killed in the
middle of a track and the recovery offer brings back every finished frame, the find and
the edits. Before, the recovery file was written every three minutes: after a crash in a
one-minute *Track both* only the import came back."""
import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow

CHILD = textwrap.dedent("""
    import json, sys, time
    from PySide6.QtCore import QSettings, QTimer
    from fluorogui.gui.app import make_application
    from fluorogui.gui.main_window import MainWindow

    app = make_application()
    window = MainWindow(settings=QSettings(sys.argv[2], QSettings.Format.IniFormat), with_3d=False)
    window.open_project(sys.argv[1], ask=False)
    s = window.controller.session

    def say(**what):
        print(json.dumps(what), flush=True)

    def found(_result):
        say(found={c: s.pose(c, 0).tolist() for c in s.components()})
        s.set_pose("tibial", 2, s.pose("tibial", 2) + [1.5, 0, 0, 0, 0, 0], text="Edit pose")  # an edit
        say(edited=s.pose("tibial", 2).tolist())
        window.runner.finished.disconnect(found)
        window.controller.set_component("femoral")
        window.controller.set_frame(0)
        window.tasks.track_frames()

    def tracked(item):  # after the window stored it (connected later)
        say(stored=item.frame, pose=s.pose("femoral", item.frame).tolist(),
            status=str(s.pose_record("femoral", item.frame).status))
        if item.frame == 1:  # the GUI thread stores the results: frame 2 cannot land before the kill
            time.sleep(600)

    window.runner.item.connect(tracked)
    window.runner.finished.connect(found)
    QTimer.singleShot(0, window.tasks.find_implants)
    app.exec()
""")


def test_killed_in_the_middle_of_a_track_every_finished_frame_comes_back(window, demo, tmp_path, qtbot, dialogs):
    env = dict(os.environ, FLUOROGUI_DATA_DIR=os.environ["FLUOROGUI_DATA_DIR"], QT_QPA_PLATFORM="offscreen",
               PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(demo), str(tmp_path / "child.ini")],
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)
    said = {"stored": {}}
    try:
        for line in child.stdout:
            what = json.loads(line)
            if "stored" in what:
                said["stored"][what["stored"]] = (what["pose"], what["status"])
                if len(said["stored"]) == 2:  # frames 0 and 1 done, frame 2 in flight
                    child.send_signal(signal.SIGKILL)
                    break
            else:
                said.update(what)
    finally:
        child.kill()
        child.wait(30)
    assert sorted(said["stored"]) == [0, 1] and "found" in said and "edited" in said

    # a new app after the crash: the recovery offer (answered Yes) brings it all back
    from PySide6.QtWidgets import QMessageBox

    dialogs["answers"].append(QMessageBox.StandardButton.Yes)
    assert window.offer_recovery()
    s = window.controller.session
    for frame, (pose, status) in said["stored"].items():
        record = s.pose_record("femoral", frame)
        assert str(record.status) == status == "matched"
        np.testing.assert_allclose(record.pose, pose, atol=1e-9)
        assert s.outline_points((frame, 0, "femoral")) is not None  # its automatic outlines too
    np.testing.assert_allclose(s.pose("tibial", 0), said["found"]["tibial"], atol=1e-9)  # the find
    np.testing.assert_allclose(s.pose("tibial", 2), said["edited"], atol=1e-9)  # the edit
    assert s.pose_record("femoral", 2) is None or str(s.pose_record("femoral", 2).status) != "matched"
    assert s.path == Path(demo)  # recovered as the project it came from
