"""Run the validation protocols and write ``docs/validation/results.json`` for the docs.

Too slow for every docs build (one to two hours on the shared 2-core development machine), so the
file is committed and ``docs/build.sh`` renders it (``docs/_ext/validation_results.py``).
Run this again after a change to the engine, then commit the new file::

    python docs/validation/regenerate.py --data PATH/TO/biplane-tka [--python PY] [--quick]

``--data`` is a folder laid out like the biplane data set the tests use (``models/``,
``calibration/``, ``pairs.csv``, ``cam1/``, ``cam2/``); its two implant meshes are the ones
validated. ``--python`` picks the interpreter whose installed fluorogui runs the commands
(default: this one); its ``fluorogui --version`` is the version stamped. ``--quick`` runs
every protocol with fewer cases, to try the script.

Each run is one ``fluorogui validate ... --out DIR`` (or ``fluorogui bench ... --json``)
command; its ``results.json`` goes into the file unchanged, with the command line and its
wall time. The file is stamped with the version, the date and the machine.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

HERE = Path(__file__).resolve().parent


def runs(data: Path, quick: bool) -> list[dict]:
    """The protocols: (name, kind, title, arguments after ``fluorogui``)."""
    fem, tib = data / "models" / "femoral_component.stl", data / "models" / "tibial_component.stl"
    cams = ["--camera", str(data / "calibration" / "cam1_mayacam2.txt"),
            "--camera", str(data / "calibration" / "cam2_mayacam2.txt")]
    reference = HERE.parents[1] / "tests" / "data" / "biplane_reference_poses.csv"
    flexions = ["45"] if quick else ["30", "45", "60", "90"]
    starts = "2" if quick else "5"
    frames = "2" if quick else "4"
    both = ["--model", str(fem), "--model", str(tib)]
    return [
        {"name": "idealized-silhouette", "kind": "idealized",
         "args": ["validate", "idealized", *both, "--renderer", "silhouette", "--flexion", *flexions,
                  "--starts", starts]},
        {"name": "idealized-xray", "kind": "idealized",
         "args": ["validate", "idealized", *both, "--flexion", *flexions, "--starts", starts]},
        # one view: the translation along the beam is the weak direction; the page counts
        # starts within 2 mm (any direction) and 0.05 degrees
        {"name": "idealized-single-view", "kind": "idealized", "basin": [2.0, 0.05],
         "args": ["validate", "idealized", *both, "--flexion", *(flexions[1::2] or flexions),
                  "--starts", "2" if quick else "3", "--single-view"]},
        {"name": "spheres", "kind": "spheres",
         "args": ["validate", "spheres", "--method", "fast", "--starts", "3" if quick else "10"]},
        {"name": "repeatability-femoral", "kind": "repeatability",
         "args": ["validate", "repeatability", *cams, "--model", str(fem), "--reference", str(reference),
                  "--pairs", str(data / "pairs.csv"), "--component", "femoral", "--frames", frames,
                  "--starts", starts]},
        {"name": "repeatability-tibial", "kind": "repeatability",
         "args": ["validate", "repeatability", *cams, "--model", str(tib), "--reference", str(reference),
                  "--pairs", str(data / "pairs.csv"), "--component", "tibial", "--frames", frames,
                  "--starts", starts]},
        {"name": "bench", "kind": "bench",
         "args": ["bench", *both, "--method", "fast", "paper", "--starts", "3", "--json"]},
    ]


def _shown(args: list[str], data: Path) -> str:
    """The command line as a user would type it: the data folder written as DATA."""
    text = shlex.join(["fluorogui", *args])
    return text.replace(str(data), "DATA").replace(str(HERE.parents[1]) + "/", "")


def machine() -> dict:
    import cv2
    import numpy
    import scipy

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError, AttributeError):
        memory = float("nan")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {"cpu": cpu, "cores": os.cpu_count(), "memory_gib": round(memory, 1),
            "platform": f"{platform.system()} {platform.release()}", "python": platform.python_version(),
            "numpy": numpy.__version__, "scipy": scipy.__version__, "opencv": cv2.__version__,
            "load_average": round(load, 1)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True, help="the biplane data folder (models/, pairs.csv, ...)")
    parser.add_argument("--python", default=sys.executable, help="interpreter whose fluorogui runs the commands")
    parser.add_argument("--out", type=Path, default=HERE / "results.json")
    parser.add_argument("--quick", action="store_true", help="fewer cases, to try the script")
    args = parser.parse_args(argv)
    data = args.data.resolve()
    if not (data / "models" / "femoral_component.stl").is_file():
        parser.error(f"{data}: not a biplane data folder (no models/femoral_component.stl)")
    fluorogui = [args.python, "-m", "fluorogui"]
    version = subprocess.run([*fluorogui, "--version"], capture_output=True, text=True, check=True).stdout.split()[-1]
    started, t0 = machine(), time.perf_counter()
    done = []
    with tempfile.TemporaryDirectory(prefix="fluorogui-validation-") as tmp:
        for run in runs(data, args.quick):
            argv_run = list(run["args"])
            out_dir = Path(tmp) / run["name"]
            if run["kind"] != "bench":
                argv_run += ["--out", str(out_dir)]
            print(f"regenerate: {_shown(argv_run, data)}", file=sys.stderr, flush=True)
            t = time.perf_counter()
            proc = subprocess.run([*fluorogui, *argv_run], capture_output=True, text=True)
            if proc.returncode != 0:
                sys.stderr.write(proc.stdout[-3000:] + proc.stderr[-3000:])
                print(f"regenerate: {run['name']} failed (exit {proc.returncode})", file=sys.stderr)
                return 1
            if run["kind"] == "bench":
                results = json.loads(proc.stdout.strip().splitlines()[-1])
            else:
                results = json.loads((out_dir / "results.json").read_text())
            shown = ["OUT" if a == str(out_dir) else a for a in argv_run]
            entry = {"name": run["name"], "kind": run["kind"], "command": _shown(shown, data),
                     "seconds": round(time.perf_counter() - t, 1), "results": results}
            if "basin" in run:
                entry["basin"] = run["basin"]
            done.append(entry)
            print(f"regenerate: {run['name']} done in {entry['seconds']:.0f} s", file=sys.stderr, flush=True)
    stamp = {"fluorogui_version": version, "date": date.today().isoformat(),
             "seconds": round(time.perf_counter() - t0, 1), "machine": started,
             "regenerate": "python docs/validation/regenerate.py --data DATA" + (" --quick" if args.quick else ""),
             "quick": args.quick}
    args.out.write_text(json.dumps({"stamp": stamp, "runs": done}, indent=1) + "\n", encoding="utf-8")
    print(f"regenerate: wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
