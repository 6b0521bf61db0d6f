"""Build the standalone fluorogui (a one-folder PyInstaller build) and, with ``--check``,
prove it works like the pip-installed one.

    python packaging/build.py            # icons, then dist/fluorogui/ (a few minutes)
    python packaging/build.py --check    # ... then the built --version and a headless match
    python packaging/build.py --check-only   # check an existing build

Run it with the project's virtualenv (``.venv/bin/python``); PyInstaller comes from the
optional ``[build]`` extra and is installed into that environment if missing. Prints the
build time, the folder size and the cold start time of the built ``--version``.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
DIST = REPO / "dist"
WORK = REPO / "build" / "pyinstaller"
APP_DIR = DIST / "fluorogui"
ICON_SVG = REPO / "fluorogui" / "resources" / "icons" / "app.svg"
ICON_DIR = HERE / "icons"
ICON_SIZES = (16, 24, 32, 48, 64, 128, 256, 512)

# Left in the folder by PyInstaller's Qt hooks but never used: other languages' Qt
# messages (the UI is English), and Qt plugins of modules fluorogui does not use.
TRIM_GLOBS = (
    "_internal/PySide6/Qt/translations/*",
    "_internal/PySide6/Qt/plugins/qmltooling",
    "_internal/PySide6/Qt/plugins/multimedia",
    "_internal/PySide6/Qt/plugins/sqldrivers",
    "_internal/PySide6/Qt/plugins/networkinformation",
    "_internal/PySide6/Qt/plugins/tls",
    "_internal/PySide6/Qt/plugins/position",
    "_internal/PySide6/Qt/plugins/designer",
    "_internal/PySide6/Qt/qml",
    "_internal/**/tests",
    "_internal/cv2/data",  # OpenCV's face-detector cascades
    "_internal/matplotlib/mpl-data/sample_data",
)


def say(message: str) -> None:
    print(f"build: {message}", flush=True)


def ensure_pyinstaller() -> None:
    try:
        import PyInstaller  # noqa: F401
    except ImportError:
        say("PyInstaller missing: installing the [build] extra into this environment")
        subprocess.run([sys.executable, "-m", "pip", "install", "-q", "-e", f"{REPO}[build]"], check=True)


def make_icons() -> list[Path]:
    """The application icon in platform sizes (PNG for Linux, .ico for Windows, .icns for
    macOS), rendered from the one SVG; skipped when they are newer than the SVG."""
    ICON_DIR.mkdir(exist_ok=True)
    pngs = [ICON_DIR / f"fluorogui-{s}.png" for s in ICON_SIZES]
    targets = [*pngs, ICON_DIR / "fluorogui.ico", ICON_DIR / "fluorogui.icns"]
    svg_time = ICON_SVG.stat().st_mtime
    if all(p.exists() and p.stat().st_mtime >= svg_time for p in targets):
        return targets
    from PySide6.QtCore import Qt
    from PySide6.QtGui import QGuiApplication, QImage, QPainter
    from PySide6.QtSvg import QSvgRenderer

    app = QGuiApplication.instance() or QGuiApplication(["build", "-platform", "offscreen"])  # noqa: F841
    renderer = QSvgRenderer(str(ICON_SVG))
    for size, path in zip(ICON_SIZES, pngs):
        image = QImage(size, size, QImage.Format.Format_ARGB32)
        image.fill(Qt.GlobalColor.transparent)
        painter = QPainter(image)
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        renderer.render(painter)
        painter.end()
        image.save(str(path))
    from PIL import Image

    big = Image.open(ICON_DIR / "fluorogui-512.png")
    big.save(ICON_DIR / "fluorogui.ico", sizes=[(s, s) for s in (16, 24, 32, 48, 64, 128, 256)])
    big.save(ICON_DIR / "fluorogui.icns")
    say(f"icons written to {ICON_DIR.relative_to(REPO)}")
    return targets


def folder_size(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file() and not p.is_symlink())


def trim(app_dir: Path) -> int:
    """Delete what the app never uses; returns the bytes saved."""
    before = folder_size(app_dir)
    for pattern in TRIM_GLOBS:
        for path in app_dir.glob(pattern):
            if path.is_dir():
                shutil.rmtree(path)
            elif path.exists():
                path.unlink()
    return before - folder_size(app_dir)


def strip_vtk(app_dir: Path) -> int:
    """Strip the symbol tables off VTK's shared libraries (Linux; its core library drops
    from 98 to 62 MB). Only VTK's: stripping everything (PyInstaller's strip=True) breaks
    numpy's OpenBLAS. Returns the bytes saved."""
    strip = shutil.which("strip")
    if not sys.platform.startswith("linux") or strip is None:
        return 0
    libraries = sorted((app_dir / "_internal" / "vtkmodules").glob("*.so"))
    before = sum(p.stat().st_size for p in libraries)
    subprocess.run([strip, "--strip-unneeded", *map(str, libraries)], check=True)
    return before - sum(p.stat().st_size for p in libraries)


def build() -> None:
    ensure_pyinstaller()
    make_icons()
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "PyInstaller", "--noconfirm", "--clean", "--log-level", "WARN",
                    "--distpath", str(DIST), "--workpath", str(WORK), str(HERE / "fluorogui.spec")],
                   check=True, cwd=REPO)
    seconds = time.perf_counter() - t0
    saved = trim(APP_DIR) + strip_vtk(APP_DIR)
    for name in ("fluorogui.desktop", "io.github.fluorogui.metainfo.xml"):
        shutil.copy2(HERE / name, APP_DIR / name)
    shutil.copy2(ICON_DIR / "fluorogui-256.png", APP_DIR / "fluorogui.png")
    say(f"built {APP_DIR} in {seconds:.0f} s; folder {folder_size(APP_DIR) / 1e6:.0f} MB "
        f"(trimmed {saved / 1e6:.0f} MB)")


def _executable() -> Path:
    return APP_DIR / ("fluorogui.exe" if sys.platform == "win32" else "fluorogui")


def _write_scene(folder: Path) -> tuple[list[str], list[float]]:
    """A generated two-view scene (rendered images of the procedural femoral component at
    45 degrees flexion) and the match arguments with a start 4 mm / 5 degrees off."""
    import numpy as np
    import pyvista as pv

    from fluorogui.core.projection.mesh import prepare_mesh
    from fluorogui.core.projection.pose import transform_points
    from fluorogui.io.calibration import save_view_json
    from fluorogui.io.images import write_image
    from fluorogui.simulation.phantoms import femoral_component_mesh
    from fluorogui.simulation.protocols import dual_orthogonal_views, flexion_pose
    from fluorogui.simulation.render import render_fluoro

    v, f = femoral_component_mesh()
    mesh = prepare_mesh(v, f)
    truth = flexion_pose(v, 45.0)
    world = transform_points(truth, mesh.vertices)
    rng = np.random.default_rng(0)
    args = ["match"]
    for k, view in enumerate(dual_orthogonal_views()):
        cam, img = folder / f"cam{k + 1}.json", folder / f"img{k + 1}.png"
        save_view_json(view, cam)
        write_image(img, render_fluoro(view, [(world, mesh.faces)], rng), bits=16)
        args += ["--camera", str(cam), "--image", str(img)]
    model = folder / "femur.stl"
    pv.PolyData(v, np.column_stack([np.full(len(f), 3), f]).ravel()).save(str(model))
    start = truth + np.array([4.0, -3.0, 2.0, 5.0, -4.0, 3.0])
    args += ["--model", str(model), "--start", *[f"{x:.6f}" for x in start], "--json"]
    return args, [float(x) for x in truth]


def _run_json(command: list[str]) -> tuple[dict, float]:
    t0 = time.perf_counter()
    proc = subprocess.run(command, capture_output=True, text=True, timeout=600)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"build: check failed: {' '.join(command[:2])} exited {proc.returncode}: {proc.stderr.strip()}")
    return json.loads(proc.stdout), seconds


def _start_gui(exe: Path) -> dict | None:
    """Start the built app on the demo (a fresh data folder, so the demo is generated) and
    let it quit once the window shows it (``FLUOROGUI_SMOKE_TEST``); under Xvfb when
    there is no display."""
    import os

    with tempfile.TemporaryDirectory(prefix="fluorogui-gui-check-") as tmp:
        env = dict(os.environ, FLUOROGUI_SMOKE_TEST="1", FLUOROGUI_DATA_DIR=tmp, XDG_CONFIG_HOME=tmp)
        command = [str(exe)]
        if not env.get("DISPLAY") and not env.get("WAYLAND_DISPLAY"):
            if shutil.which("xvfb-run") is None:
                say("no display and no xvfb-run: GUI start not checked")
                return {"title": "not checked", "frames": 0, "started_s": float("nan"), "wall_s": float("nan")}
            command = ["xvfb-run", "-a", "-s", "-screen 0 1920x1080x24", *command]
        t0 = time.perf_counter()
        proc = subprocess.run(command, capture_output=True, text=True, timeout=600, env=env)
        wall = time.perf_counter() - t0
    lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
    if proc.returncode != 0 or not lines:
        say(f"FAILED: the built app did not start (exit {proc.returncode}): {proc.stderr.strip()[-800:]}")
        return None
    started = json.loads(lines[-1])
    if "demo" not in started.get("title", "") or not started.get("frames"):
        say(f"FAILED: the built app did not open the demo: {started}")
        return None
    started["wall_s"] = wall
    return started


def check() -> int:
    """Run the built program's --version and a headless match on a generated scene, and
    compare the pose with the pip-installed program's; returns the exit code."""
    exe = _executable()
    if not exe.exists():
        say(f"no build at {exe}; run python packaging/build.py first")
        return 2
    from fluorogui import __version__

    t0 = time.perf_counter()
    proc = subprocess.run([str(exe), "--version"], capture_output=True, text=True, timeout=300)
    cold = time.perf_counter() - t0
    if proc.returncode != 0 or proc.stdout.strip() != f"fluorogui {__version__}":
        say(f"--version gave {proc.stdout.strip()!r} (exit {proc.returncode}), expected 'fluorogui {__version__}'")
        return 1
    say(f"built --version: {proc.stdout.strip()} ({cold:.2f} s, first start)")
    started = _start_gui(exe)
    if started is None:
        return 1
    say(f"built app: window with the demo ({started['title']}, {started['frames']} frames) in "
        f"{started['started_s']:.1f} s (first start, demo generated: {started['wall_s']:.1f} s wall)")
    with tempfile.TemporaryDirectory(prefix="fluorogui-check-") as tmp:
        args, truth = _write_scene(Path(tmp))
        built, built_s = _run_json([str(exe), *args])
        installed, installed_s = _run_json([sys.executable, "-m", "fluorogui", *args])
    import numpy as np

    built_pose, installed_pose = np.array(built["pose"]), np.array(installed["pose"])
    gap = np.abs(built_pose - installed_pose)
    error = np.abs(built_pose - np.array(truth))
    say(f"match: built {built_s:.1f} s, installed {installed_s:.1f} s; largest pose difference "
        f"{gap[:3].max():.2e} mm, {gap[3:].max():.2e} deg; built vs truth {error[:3].max():.3f} mm, "
        f"{error[3:].max():.3f} deg")
    if gap[:3].max() > 1e-6 or gap[3:].max() > 1e-6:
        say("FAILED: the built program's pose differs from the pip-installed one")
        return 1
    say("OK: the built program matches exactly like the pip-installed one")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="after building, run the built program's checks")
    parser.add_argument("--check-only", action="store_true", help="check an existing build, do not build")
    parser.add_argument("--icons-only", action="store_true", help="only (re)make the icons")
    args = parser.parse_args(argv)
    if args.icons_only:
        make_icons()
        return 0
    if not args.check_only:
        build()
    if args.check or args.check_only:
        return check()
    return 0


if __name__ == "__main__":
    sys.exit(main())
