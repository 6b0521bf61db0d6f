"""Benchmark the 3D scene on the real biplane data: frame rate while rotating, image and pose updates.

Usage (no screen: under Xvfb):
    xvfb-run -a -s "-screen 0 1920x1080x24" .venv/bin/python benchmarks/bench_scene3d.py [--data DIR]

Runs three back ends, each in its own process: an off-screen ``pv.Plotter``, the panel's
fallback (off-screen plotter + QLabel, ``QT_QPA_PLATFORM=offscreen``) and the interactive
``QtInteractor`` (``QT_QPA_PLATFORM=xcb``, skipped when it cannot start). Prints a table.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "data" / "biplane-tka"
WINDOW = (1280, 800)
FRAMES = 60


def load_inputs(data: Path):
    from fluorogui.io.calibration import load_view
    from fluorogui.io.images import read_image
    from fluorogui.io.meshes.read import load_mesh

    views = [load_view(data / "calibration" / f"cam{c}_mayacam2.txt") for c in (1, 2)]
    images = [read_image(data / "cam1" / "000000.tif"), read_image(data / "cam2" / "000522.tif")]
    models = {c: load_mesh(data / "models" / f"{c}_component.stl") for c in ("femoral", "tibial")}
    pose = np.array([-55.5217, -37.8811, -124.8751, -125.8613, 174.0007, 72.3379])  # frame 0, femoral
    return views, images, models, pose


def build(scene, inputs, timings):
    views, images, models, pose = inputs
    t = time.perf_counter()
    scene.set_views(views)
    timings["set_views_ms"] = 1e3 * (time.perf_counter() - t)
    t = time.perf_counter()
    for component, (vertices, faces) in models.items():
        scene.set_model(component, vertices, faces)
        scene.set_pose(component, pose)
    timings["set_model_x2_ms"] = 1e3 * (time.perf_counter() - t)
    timings["points"] = int(sum(len(v) for v, _ in models.values()))
    timings["triangles"] = int(sum(len(f) for _, f in models.values()))
    scene.set_images(images)
    for k, view in enumerate(views):
        from fluorogui.core.projection.pose import transform_points

        uv = view.project(transform_points(pose, models["femoral"][0][::40]))
        scene.set_rays(k, uv)
    scene.camera_preset("iso")


def gl_renderer(plotter) -> str:
    try:
        caps = plotter.render_window.ReportCapabilities()
        for line in caps.splitlines():
            if "renderer string" in line:
                return line.split(":", 1)[1].strip()
    except Exception:  # noqa: BLE001
        pass
    return "?"


def median_ms(fn, repeats: int) -> float:
    samples = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t)
    return 1e3 * float(np.median(samples))


def updates(scene, render, inputs, timings):
    """set_images / set_pose costs, alone and followed by the render that shows them."""
    views, images, _, pose = inputs
    rng = np.random.default_rng(0)
    second = [np.ascontiguousarray(images[1]), np.ascontiguousarray(images[0])]
    pairs = [images, second]
    i = [0]

    def swap():
        i[0] += 1
        scene.set_images(pairs[i[0] % 2])

    def swap_window():
        i[0] += 1
        scene.set_images(pairs[i[0] % 2], window_levels=[(0.05, 0.95), (0.05, 0.95)])

    def swap_render():
        swap()
        render()

    def nudge():
        scene.set_pose("femoral", pose + rng.normal(0, 0.5, 6))

    def nudge_render():
        nudge()
        render()

    saved = scene.render_callback
    scene.render_callback = lambda: None  # the update alone, no render request
    timings["set_images_2x1024_ms"] = median_ms(swap, 20)
    timings["set_images_fixed_window_ms"] = median_ms(swap_window, 20)
    timings["set_pose_ms"] = median_ms(nudge, 500)
    timings["set_images+render_ms"] = median_ms(swap_render, 10)  # includes the texture upload
    timings["set_pose+render_ms"] = median_ms(nudge_render, 20)
    scene.render_callback = saved


def rotate(plotter, render, timings, key):
    cam = plotter.camera
    render()
    t = time.perf_counter()
    for _ in range(FRAMES):
        cam.Azimuth(360.0 / FRAMES)
        plotter.renderer.reset_camera_clipping_range()
        render()
    timings[key] = FRAMES / (time.perf_counter() - t)


def run_plotter(data: Path) -> dict:
    import pyvista as pv

    from fluorogui.gui.scene.scene3d import FluoroScene

    inputs = load_inputs(data)
    timings = {"backend": "pv.Plotter(off_screen)"}
    plotter = pv.Plotter(off_screen=True, window_size=list(WINDOW))
    scene = FluoroScene(plotter)
    build(scene, inputs, timings)
    t = time.perf_counter()
    plotter.screenshot(return_img=True)
    timings["first_render_ms"] = 1e3 * (time.perf_counter() - t)
    timings["gl"] = gl_renderer(plotter)
    def render_readback():
        plotter.render()
        plotter.screenshot(return_img=True)  # reads the frame back (does not re-render)

    rotate(plotter, plotter.render, timings, "fps_render")
    rotate(plotter, render_readback, timings, "fps_render+readback")
    updates(scene, plotter.render, inputs, timings)
    plotter.close()
    return timings


def run_widget(data: Path, interactive: bool) -> dict:
    from PySide6.QtWidgets import QApplication

    app = QApplication.instance() or QApplication([])
    from fluorogui.gui.scene.scene_widget import Scene3DWidget

    inputs = load_inputs(data)
    widget = Scene3DWidget(interactive=interactive, window_size=WINDOW)
    widget.resize(WINDOW[0], WINDOW[1] + 30)
    widget.show()
    for _ in range(10):
        app.processEvents()
    timings = {"backend": ("QtInteractor" if interactive else "fallback QLabel") + f" ({app.platformName()})"}
    build(widget.scene, inputs, timings)
    t = time.perf_counter()
    widget.grab_image()
    timings["first_render_ms"] = 1e3 * (time.perf_counter() - t)
    timings["gl"] = gl_renderer(widget.plotter)

    def render():
        widget.request_render()
        widget._do_render()  # what the coalescing timer runs
        widget._timer.stop()
        app.processEvents()

    rotate(widget.plotter, render, timings, "fps_render")
    updates(widget.scene, render, inputs, timings)
    widget.close()
    return timings


COLUMNS = [
    ("fps_render", "rotate fps", "{:.1f}"),
    ("fps_render+readback", "fps+readback", "{:.1f}"),
    ("first_render_ms", "1st render ms", "{:.0f}"),
    ("set_views_ms", "set_views ms", "{:.1f}"),
    ("set_model_x2_ms", "set_model x2 ms", "{:.0f}"),
    ("set_images_2x1024_ms", "set_images ms", "{:.1f}"),
    ("set_images_fixed_window_ms", "set_images fixed-win ms", "{:.1f}"),
    ("set_images+render_ms", "set_images+render ms", "{:.1f}"),
    ("set_pose_ms", "set_pose ms", "{:.3f}"),
    ("set_pose+render_ms", "set_pose+render ms", "{:.1f}"),
]


def print_table(results: list[dict]) -> None:
    print()
    first = results[0] if results else {}
    print(f"window {WINDOW[0]}x{WINDOW[1]}, {FRAMES} frames; models: {first.get('points', '?')} points, "
          f"{first.get('triangles', '?')} triangles (both components); GL: {first.get('gl', '?')}")
    width = max(len(r["backend"]) for r in results) if results else 10
    print(f"{'metric':<26}" + "".join(f"{r['backend']:>{width + 2}}" for r in results))
    for key, title, fmt in COLUMNS:
        cells = [fmt.format(r[key]) if key in r else "-" for r in results]
        print(f"{title:<26}" + "".join(f"{c:>{width + 2}}" for c in cells))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--backend", choices=("all", "plotter", "fallback", "qt"), default="all")
    args = parser.parse_args(argv)
    if not (args.data / "pairs.csv").is_file():
        print(f"bench_scene3d: no data at {args.data}", file=sys.stderr)
        return 2
    if args.backend == "plotter":
        print(json.dumps(run_plotter(args.data)))
        return 0
    if args.backend in ("fallback", "qt"):
        print(json.dumps(run_widget(args.data, interactive=args.backend == "qt")))
        return 0

    results = []
    for backend, platform in (("plotter", "offscreen"), ("fallback", "offscreen"), ("qt", "xcb")):
        env = {**os.environ, "QT_QPA_PLATFORM": platform}
        proc = subprocess.run([sys.executable, __file__, "--data", str(args.data), "--backend", backend],
                              capture_output=True, text=True, env=env, cwd=REPO)
        lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
        if proc.returncode != 0 or not lines:
            print(f"bench_scene3d: {backend} back end failed ({proc.returncode}): {proc.stderr.strip()[-300:]}")
            continue
        results.append(json.loads(lines[-1]))
    print_table(results)
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    raise SystemExit(main())
