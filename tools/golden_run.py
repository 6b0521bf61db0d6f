"""A golden run: the command line's outputs, the project files and the poses of a fixed
set of commands, with what varies from run to run (seconds, temporary paths) taken out,
written to a folder. Run it before a change that must not change behaviour and after it,
then compare the two folders (``diff -r``): they must be identical.

    python tools/golden_run.py OUT_DIR [--no-real]

The commands: the demo (``demo``, ``find``, ``track``, every export, ``kinematics``) and,
where ../shared/data is present, the real biplane data (``import``, ``track`` of five
frames, ``match`` of one component from a reference pose, ``export``). Takes a minute or
two.
"""
from __future__ import annotations

import argparse
import csv
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "biplane-tka"
REFERENCE = ROOT / "tests" / "data" / "biplane_reference_poses.csv"
VARYING_KEYS = {"seconds", "time", "elapsed_s", "created", "saved_at"}
SECONDS_IN_TEXT = re.compile(r"\d+(\.\d+)? s\b")


def _strip(value):
    """JSON data without the keys that vary from run to run."""
    if isinstance(value, dict):
        return {k: _strip(v) for k, v in value.items() if k not in VARYING_KEYS}
    if isinstance(value, list):
        return [_strip(v) for v in value]
    return value


def _clean_text(text: str, work: Path) -> str:
    text = text.replace(str(work), "<work>")
    return SECONDS_IN_TEXT.sub("<t> s", text)


def _run(out: Path, work: Path, name: str, *args) -> None:
    """Run one command line; keep its exit status, stdout (JSON lines stripped) and stderr."""
    done = subprocess.run([sys.executable, "-m", "fluorogui", *map(str, args)], cwd=work, capture_output=True,
                          text=True, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin",
                                          "FLUOROGUI_DATA_DIR": str(work / "appdata")})
    lines = []
    for line in done.stdout.splitlines():
        try:
            lines.append(json.dumps(_strip(json.loads(line)), sort_keys=True))
        except ValueError:
            lines.append(_clean_text(line, work))
    (out / f"{name}.txt").write_text(f"exit {done.returncode}\n--- stdout\n" + "\n".join(lines)
                                     + "\n--- stderr\n" + _clean_text(done.stderr, work))


def _keep_file(out: Path, work: Path, source: Path, name: str) -> None:
    if source.is_dir():
        for child in sorted(source.iterdir()):
            _keep_file(out, work, child, f"{name}__{child.name}")
        return
    if not source.exists():
        (out / name).write_text("(missing)\n")
        return
    if source.suffix in (".fluoro", ".json"):
        text = source.read_text()
        try:
            data = _strip(json.loads(text))
            (out / name).write_text(_clean_text(json.dumps(data, indent=1, sort_keys=True), work))
            return
        except ValueError:
            pass
    if source.suffix in (".csv", ".tra", ".jts", ".mot", ".txt"):
        (out / name).write_text(_clean_text(source.read_text(), work))
    else:
        shutil.copy(source, out / name)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--no-real", action="store_true")
    args = parser.parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="fluorogui-golden-"))
    run = lambda name, *a: _run(out, work, name, *a)  # noqa: E731
    run("01_demo", "demo", "demo.fluoro", "--frames", "3")
    run("02_find", "find", "demo.fluoro", "--frames", "0", "--json")
    run("03_track", "track", "demo.fluoro", "--json")
    run("04_find_kept", "find", "demo.fluoro", "--frames", "1", "--json")
    run("05_export", "export", "demo.fluoro", "--poses", "poses.csv", "--kinematics", "kin.csv", "--tra", "p.tra",
        "--jts", "jts", "--view", "1", "--c3d", "k.c3d", "--mot", "k.mot", "--fps", "30")
    models = work / "demo_data" / "models"
    run("06_kinematics", "kinematics", "--poses", "poses.csv", "--side", "right", "--out", "kin2.csv",
        "--femoral-mesh", next(models.glob("fem*")), "--tibial-mesh", next(models.glob("tib*")))
    for name in ("demo.fluoro", "poses.csv", "kin.csv", "p.tra", "jts", "k.mot", "k.c3d", "kin2.csv"):
        _keep_file(out, work, work / name, f"demo__{name}")
    if DATA.is_dir() and not args.no_real:
        run("10_import", "import", DATA, "--out", "real.fluoro", "--side", "right")
        run("11_track", "track", "real.fluoro", "--frames", "0:60", "--json")
        run("12_export", "export", "real.fluoro", "--poses", "real_poses.csv")
        with open(REFERENCE, newline="") as handle:
            ref = next(r for r in csv.DictReader(handle) if r["frame"] == "50" and r["component"] == "femoral")
        pairs = {r["frame"]: r for r in csv.DictReader(open(DATA / "pairs.csv", newline=""))}
        start = [float(ref[k]) + d for k, d in zip(("x", "y", "z", "alpha", "beta", "gamma"), (1, -1, 1, 1, -1, 1))]
        run("13_match", "match", "--camera", DATA / "calibration" / "cam1_mayacam2.txt",
            "--camera", DATA / "calibration" / "cam2_mayacam2.txt", "--image", DATA / pairs["50"]["cam1"],
            "--image", DATA / pairs["50"]["cam2"], "--model", DATA / "models" / "femoral_component.stl",
            "--json", "--start", *start)
        for name in ("real.fluoro", "real_poses.csv"):
            _keep_file(out, work, work / name, f"real__{name}")
    shutil.rmtree(work, ignore_errors=True)
    print(f"golden run written to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
