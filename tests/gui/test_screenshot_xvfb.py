"""The real main window on a real (virtual) X display: the screen shows the images and the models.

Runs ``fluorogui.gui.snapshot`` in a subprocess with Qt's xcb platform, with the 3D panel
as an embedded OpenGL view and as the image view used on software OpenGL; skipped where
there is no X display (packaging/test.sh runs the suite under Xvfb, so CI always has one).
"""
import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(not os.environ.get("DISPLAY"), reason="needs an X display (run under xvfb-run)")


@pytest.mark.parametrize("gl", ["interactive", "image"])
@pytest.mark.slow
def test_main_window_screenshot_shows_images_and_models(tmp_path, gl):
    out = tmp_path / "window.png"
    env = dict(os.environ, QT_QPA_PLATFORM="xcb", FLUOROGUI_DATA_DIR=str(tmp_path / "data"), FLUOROGUI_GL=gl)
    run = subprocess.run([sys.executable, "-m", "fluorogui.gui.snapshot", str(out), "--size", "1280x800"],
                         env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    info = json.loads(run.stdout.strip().splitlines()[-1])
    import cv2

    shot = cv2.cvtColor(cv2.imread(str(out), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB).astype(int)
    assert shot.shape[0] >= 700 and shot.shape[1] >= 1200

    def crop(name):
        x, y, w, h = info["regions"][name]
        return shot[y:y + h, x:x + w]

    for name in ("view1", "view2"):
        panel = crop(name)
        grey = panel.mean(axis=2)
        assert grey.std() > 20, f"{name} looks blank"
        # the fluoroscopic field (bright) and the dark implants are both there
        assert (grey > 150).mean() > 0.1 and (grey < 60).mean() > 0.01
    assert info["scene_interactive"] is (gl == "interactive")  # the embedded OpenGL view, or its image
    scene = crop("scene")
    r, g, b = scene[..., 0], scene[..., 1], scene[..., 2]
    assert scene.mean(axis=2).std() > 10, "3D panel looks blank"
    greenish = (g > r + 30) & (g > b + 15)  # the tibial model's colour (the beams are orange and blue)
    assert greenish.sum() > 50, "no tibial model in the 3D panel"
