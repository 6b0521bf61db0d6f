"""Checks that run inside the built program (``packaging/build.py --check``): what a frozen
build can lose without failing to start - a module imported by name, a codec loaded by
importlib, a plugin found through its metadata - exercised the way the app uses it.

The built program runs this instead of the app when ``FLUOROGUI_BUILD_CHECK`` names a
JSON request ``{"images": [paths], "kinematics": true}``; it prints one JSON line:
``images`` maps each path to its shape, dtype and the SHA-256 of the float32 pixels that
``fluorogui.io.images.read_image`` gives (or the one-line error), and ``kinematics``
says what the Kinematics dock showed on the demo session. build.py compares the images
with the pip-installed program's reading of the same files.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import traceback

ENV = "FLUOROGUI_BUILD_CHECK"


def read_images(paths: list[str]) -> dict:
    """``{path: {"shape", "dtype", "sha256"} or {"error"}}`` through the app's reader."""
    from fluorogui.io.images import read_image

    out = {}
    for path in paths:
        try:
            pixels = read_image(path)
            out[path] = {"shape": list(pixels.shape), "dtype": str(pixels.dtype),
                         "sha256": hashlib.sha256(pixels.tobytes()).hexdigest()}
        except Exception as exc:  # noqa: BLE001 - reported to build.py, which fails the check
            out[path] = {"error": f"{type(exc).__name__}: {exc}"}
    return out


def kinematics_dock() -> dict:
    """Open the demo session, bring the Kinematics dock to the front and draw its figure
    (matplotlib's Qt backend); what it showed."""
    from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
    from PySide6.QtWidgets import QApplication

    from fluorogui.gui.app import make_application
    from fluorogui.gui.main_window import MainWindow

    app = make_application()
    window = MainWindow()
    window.show()
    opened = window.open_demo(ask=False)
    window.knee_dock.show()
    window.knee_dock.raise_()
    for _ in range(20):
        QApplication.processEvents()
    canvases = window.knee_panel.findChildren(FigureCanvasQTAgg)
    result = {"demo": bool(opened), "frames": len(window.controller.frames), "canvases": len(canvases),
              "visible": window.knee_dock.isVisible() and not window.knee_dock.visibleRegion().isEmpty()}
    if canvases:
        canvas = canvases[0]
        canvas.draw()
        image = canvas.grab().toImage()
        colours = {image.pixel(x, y) for x in range(0, image.width(), 7) for y in range(0, image.height(), 7)}
        figure = canvas.figure
        result.update(
            backend=type(canvas).__module__, size=[image.width(), image.height()], colours=len(colours),
            axes=len(figure.axes), curves=sum(len(ax.lines) for ax in figure.axes),
            status=window.knee_panel.status.text())
    window.controller.session.history.set_clean()
    window.close()
    app.processEvents()
    return result


def main(request_path: str) -> int:
    os.environ.pop(ENV, None)  # not for the programs this one starts (Dask workers)
    report: dict = {}
    try:
        with open(request_path, encoding="utf-8") as handle:
            request = json.load(handle)
        report["images"] = read_images(list(request.get("images", [])))
        if request.get("kinematics"):
            report["kinematics"] = kinematics_dock()
    except Exception:  # noqa: BLE001 - the traceback is the check's message
        report["error"] = traceback.format_exc()
    print(json.dumps(report), flush=True)
    return 1 if "error" in report else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
