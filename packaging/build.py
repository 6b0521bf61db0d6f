"""Build the standalone fluorogui (a one-folder PyInstaller build) and, with ``--check``,
prove it works like the same checkout run from source.

    python packaging/build.py            # icons, then dist/fluorogui/ (a few minutes)
    python packaging/build.py --check    # ... then check the built program (below)
    python packaging/build.py --check-only   # check an existing build

Run it with the project's virtualenv (``.venv/bin/python``). It builds the checkout it
belongs to (put first on the path of the build and of the comparison runs), with the
libraries installed in that environment. PyInstaller comes from the ``[build]`` extra of
pyproject.toml: when missing, those packages alone are installed into the environment
(never the project itself, so an editable install keeps pointing where it did).

The check runs the built program's ``--version``; starts its GUI on the demo twice (the
first start generates the demo) and reports the start time; opens the Kinematics dock
(matplotlib's Qt backend); reads LZW, Deflate and JPEG TIFFs and JPEG Lossless, JPEG
baseline and JPEG 2000 DICOMs exactly as the source does (imagecodecs' codecs, pylibjpeg's
plugins); and runs a headless ``match`` on an LZW TIFF + JPEG Lossless DICOM scene that
must give the source's pose to 1e-6. Prints the build time, the folder size and each
check's time; any failure is one line and exit status 1.
"""
from __future__ import annotations

import argparse
import ast
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))  # this checkout's fluorogui, whatever the environment has installed
DIST = REPO / "dist"
WORK = REPO / "build" / "pyinstaller"
APP_DIR = DIST / "fluorogui"
ICON_SVG = REPO / "fluorogui" / "resources" / "icons" / "app.svg"
ICON_DIR = HERE / "icons"
ICON_SIZES = (16, 24, 32, 48, 64, 128, 256, 512)


def say(message: str) -> None:
    print(f"build: {message}", flush=True)


class CheckFailed(Exception):
    """One check of the built program failed; the message is the line to print."""


def _source_env(**extra: str) -> dict:
    """The environment of a child process that must run this checkout's fluorogui."""
    path = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    return dict(os.environ, PYTHONPATH=path, **extra)


def build_requirements() -> list[str]:
    """The ``[build]`` extra of pyproject.toml (``build = [...]``, on one line)."""
    text = (REPO / "pyproject.toml").read_text(encoding="utf-8")
    match = re.search(r"^build\s*=\s*(\[.*?\])\s*$", text, re.MULTILINE)
    if match is None:
        raise SystemExit("build: pyproject.toml has no [project.optional-dependencies] build = [...] line")
    return list(ast.literal_eval(match.group(1)))


def ensure_build_tools() -> None:
    """Install the [build] extra's packages (PyInstaller) when missing - those alone: an
    editable ``pip install -e .[build]`` would re-point the environment at this checkout."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        import PyInstaller  # noqa: F401

        version("pyinstaller-hooks-contrib")
        return
    except (ImportError, PackageNotFoundError):
        pass
    requirements = build_requirements()
    say(f"installing the build tools into this environment: {' '.join(requirements)}")
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--disable-pip-version-check", *requirements],
                   check=True)


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


def build() -> bool:
    """Build dist/fluorogui/; False (after one line saying why) when the build failed."""
    try:
        ensure_build_tools()
    except subprocess.CalledProcessError as exc:
        say(f"FAILED: pip could not install the build tools (exit status {exc.returncode}; see above)")
        return False
    make_icons()
    say(f"building {REPO} (a few minutes)")
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "PyInstaller", "--noconfirm", "--clean", "--log-level", "WARN",
                           "--distpath", str(DIST), "--workpath", str(WORK), str(HERE / "fluorogui.spec")],
                          cwd=REPO, env=_source_env())
    if proc.returncode != 0:
        say(f"FAILED: PyInstaller exited with status {proc.returncode} (its messages are above)")
        return False
    seconds = time.perf_counter() - t0
    saved = strip_vtk(APP_DIR)
    if sys.platform.startswith("linux"):
        for name in ("fluorogui.desktop", "io.github.fluorogui.metainfo.xml"):
            shutil.copy2(HERE / name, APP_DIR / name)
        shutil.copy2(ICON_DIR / "fluorogui-256.png", APP_DIR / "fluorogui.png")
    say(f"built {APP_DIR} in {seconds:.0f} s; folder {folder_size(APP_DIR) / 1e6:.0f} MB "
        f"(VTK stripped: {saved / 1e6:.0f} MB saved)")
    return True


def _executable() -> Path:
    """The built program the checks run: the console one (on Windows ``fluorogui.exe`` is
    windowed and would lose the output; the .app's program on macOS)."""
    if sys.platform == "win32":
        return APP_DIR / "fluorogui-cli.exe"
    if sys.platform == "darwin":
        return DIST / "fluorogui.app" / "Contents" / "MacOS" / "fluorogui"
    return APP_DIR / "fluorogui"


def _gui_command(exe: Path) -> list[str]:
    """``exe`` under Xvfb when there is no display (Linux CI)."""
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        if shutil.which("xvfb-run") is None:
            raise CheckFailed("no display and no xvfb-run: the built GUI cannot be checked (apt-get install xvfb)")
        return ["xvfb-run", "-a", "-s", "-screen 0 1920x1080x24", str(exe)]
    return [str(exe)]


def _run(command: list[str], what: str, env: dict | None = None, timeout: float = 600) -> tuple[str, float, float]:
    """Run ``command``: its stdout, its wall time and the time its first JSON line came
    (the built app prints one when its window shows the session); CheckFailed with the end
    of its stderr when it fails."""
    t0 = time.perf_counter()
    answered = float("nan")
    lines = []
    with tempfile.TemporaryFile(mode="w+", encoding="utf-8", errors="replace") as errors:
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=errors, text=True, env=env)
        timer = threading.Timer(timeout, proc.kill)
        timer.start()
        try:
            for line in proc.stdout:
                if line.startswith("{") and math.isnan(answered):
                    answered = time.perf_counter() - t0
                lines.append(line)
            proc.wait()
        finally:
            timer.cancel()
        seconds = time.perf_counter() - t0
        if proc.returncode != 0:
            errors.seek(0)
            tail = " | ".join(errors.read().strip().splitlines()[-3:])
            if seconds >= timeout:
                raise CheckFailed(f"{what}: no answer in {timeout:.0f} s")
            raise CheckFailed(f"{what}: exit status {proc.returncode}: {tail}")
    return "".join(lines), seconds, answered


def _display_start() -> float:
    """Seconds Xvfb takes to start and stop (xvfb-run of a program that does nothing)."""
    command = _gui_command(Path(shutil.which("true") or "/bin/true"))
    if command[0] != "xvfb-run":
        return 0.0
    return _run(command, "xvfb-run")[1]


def _last_json(stdout: str, what: str) -> dict:
    lines = [line for line in stdout.splitlines() if line.startswith("{")]
    if not lines:
        raise CheckFailed(f"{what}: printed no JSON result")
    return json.loads(lines[-1])


def check_version(exe: Path) -> None:
    from fluorogui import __version__

    out, seconds, _ = _run([str(exe), "--version"], "built --version", timeout=300)
    if out.strip() != f"fluorogui {__version__}":
        raise CheckFailed(f"built --version gave {out.strip()!r}, expected 'fluorogui {__version__}'")
    say(f"built --version: {out.strip()} ({seconds:.1f} s, first start)")


def check_gui_start(exe: Path, data: Path) -> None:
    """Start the built app on the demo and let it quit once the window shows it
    (``FLUOROGUI_SMOKE_TEST``): first with an empty data folder (the demo is generated),
    then again (the demo is cached: a user's usual start). The start time is from the
    launch to the window showing the demo, less Xvfb's own start."""
    env = dict(os.environ, FLUOROGUI_SMOKE_TEST="1", FLUOROGUI_DATA_DIR=str(data), XDG_CONFIG_HOME=str(data))
    display = _display_start()
    for attempt in ("first start, demo generated", "second start"):
        out, wall, shown = _run(_gui_command(exe), f"built app ({attempt})", env=env)
        started = _last_json(out, "built app")
        if "demo" not in started.get("title", "") or not started.get("frames"):
            raise CheckFailed(f"built app did not open the demo: {started}")
        say(f"built app ({attempt}): window with the demo ({started['frames']} frames) {shown - display:.1f} s "
            f"after launch ({started['started_s']:.1f} s of it in the app's start-up; {wall:.1f} s wall with "
            f"Xvfb {display:.1f} s and quitting)")


def _reference_images(paths: list[Path]) -> dict:
    """What this checkout's reader gives for ``paths`` (as ``frozen_check.read_images``)."""
    from fluorogui.io.images import read_image

    out = {}
    for path in paths:
        pixels = read_image(path)
        out[str(path)] = {"shape": list(pixels.shape), "dtype": str(pixels.dtype),
                          "sha256": hashlib.sha256(pixels.tobytes()).hexdigest()}
    return out


def check_in_app(exe: Path, data: Path, images: list[Path]) -> None:
    """The built program's own checks (``frozen_check``): the Kinematics dock drawn on the
    demo, and every image read to the same pixels as from source."""
    request = data / "check-request.json"
    request.write_text(json.dumps({"images": [str(p) for p in images], "kinematics": True}), encoding="utf-8")
    env = dict(os.environ, FLUOROGUI_BUILD_CHECK=str(request), FLUOROGUI_DATA_DIR=str(data), XDG_CONFIG_HOME=str(data))
    out, seconds, _ = _run(_gui_command(exe), "built app's in-app checks", env=env)
    report = _last_json(out, "built app's in-app checks")
    knee = report.get("kinematics", {})
    if not (knee.get("demo") and knee.get("visible") and knee.get("backend") == "matplotlib.backends.backend_qtagg"
            and knee.get("curves", 0) > 0 and knee.get("colours", 0) > 1):
        raise CheckFailed(f"the built app's Kinematics dock did not draw its curves: {knee}")
    say(f"built app: Kinematics dock drawn ({knee['axes']} axes, {knee['curves']} curves, "
        f"{knee['size'][0]}x{knee['size'][1]} px; {seconds:.1f} s wall)")
    expected = _reference_images(images)
    got = report.get("images", {})
    wrong = [f"{Path(path).name} ({got.get(path, {}).get('error', 'other pixels')})"
             for path, want in expected.items() if got.get(path) != want]
    if wrong:
        raise CheckFailed(f"the built program did not read {len(wrong)} of {len(expected)} images as the source "
                          f"does: {'; '.join(wrong)}")
    say(f"built app: read {', '.join(Path(p).name for p in expected)} exactly as from source")


def check_match(exe: Path, args: list[str], truth: list[float]) -> None:
    """A headless match on the LZW TIFF + JPEG Lossless DICOM scene: the built program's
    pose must be the source's."""
    import numpy as np

    built_out, built_s, _ = _run([str(exe), *args], "built match")
    source_out, source_s, _ = _run([sys.executable, "-m", "fluorogui", *args], "match from source",
                                   env=_source_env())
    built, source = np.array(json.loads(built_out)["pose"]), np.array(json.loads(source_out)["pose"])
    gap, error = np.abs(built - source), np.abs(built - np.array(truth))
    say(f"match (LZW TIFF + JPEG Lossless DICOM): built {built_s:.1f} s, from source {source_s:.1f} s; "
        f"largest pose difference {gap[:3].max():.2e} mm, {gap[3:].max():.2e} deg; built vs truth "
        f"{error[:3].max():.3f} mm, {error[3:].max():.3f} deg")
    if gap.max() > 1e-6:
        raise CheckFailed("the built program's pose differs from the source's")


def check() -> int:
    """Every check of the built program; returns the exit code."""
    exe = _executable()
    if not exe.exists():
        say(f"no build at {exe}; run python packaging/build.py first")
        return 2
    load = f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores" if hasattr(os, "getloadavg") else ""
    say(f"checking {exe} {f'({load})' if load else ''}".rstrip())
    from check_inputs import write_format_probes, write_scene

    t0 = time.perf_counter()
    failures = 0
    with tempfile.TemporaryDirectory(prefix="fluorogui-check-") as tmp:
        tmp = Path(tmp)
        for sub in ("data", "scene", "probes"):
            (tmp / sub).mkdir()
        args, truth = write_scene(tmp / "scene")
        images = [Path(a) for a in args if a.endswith((".tif", ".dcm"))] + write_format_probes(tmp / "probes")
        checks = (lambda: check_version(exe), lambda: check_gui_start(exe, tmp / "data"),
                  lambda: check_match(exe, args, truth), lambda: check_in_app(exe, tmp / "data", images))
        for run in checks:  # each failure is one line; the others still run
            try:
                run()
            except CheckFailed as exc:
                say(f"FAILED: {exc}")
                failures += 1
            except Exception as exc:  # noqa: BLE001 - e.g. a built program's output that is not JSON
                say(f"FAILED: {type(exc).__name__}: {exc}")
                failures += 1
    if failures:
        say(f"{failures} of {len(checks)} checks FAILED ({time.perf_counter() - t0:.0f} s)")
        return 1
    say(f"OK: the built program works like the source ({time.perf_counter() - t0:.0f} s of checks)")
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
    if not args.check_only and not build():
        return 1
    if args.check or args.check_only:
        return check()
    return 0


if __name__ == "__main__":
    sys.exit(main())
