"""The long fuzz run of issue 11: throw broken inputs at every loader, the command line and
the project saves, and print the counts that must all be zero.

    python tools/fuzz.py --cli 1000 --projects 500 --loaders 40 --kills 100 --full-disk 4 --large

``--cli``: command lines (bad option values, missing / folder / FIFO / empty / junk /
truncated / mutated input files) run through ``fluorogui.cli.main`` in worker processes,
and the named regression cases (``cli_cases.regression_cases``: absurd calibrations, start
poses at or behind a source, a lower-case JointTrack header; issue 44's blank and damaged
images, far-off outlines, repeated sections, non-ASCII digits, impossible angles, a
one-triangle mesh, seven start numbers), each of which must be refused naming the input at
fault (or warned about), and, with the real data beside the repository, the matches of
issue 44 that took minutes, each of which must end within 30 s (else counted as a hang);
``--projects``: mutated and hand-made nasty project files through ``load_project``, the
regression cases of projects contradicting themselves among them (and an accepted one must
save and reopen unchanged); ``--loaders``: mutations per seed file of every other loader
(calibrations of each format, images, meshes, outlines, pairs, poses); ``--kills``: a
saving child killed at random moments; ``--full-disk``: saves under ``RLIMIT_FSIZE``
limits; ``--large``: inputs near 100 MB (a long project, a project of 400,000 small
outlines, a settings object of 7 million keys, a 1.8-million-triangle mesh, a large
outline, a junk PNG) each loaded in its own process, and ``fluorogui match`` with the
large mesh and with a 250,000-triangle model (the largest matched unsimplified), for the peak memory;
every one must stay under 1.5 GB. The quick versions of these run in ``tests/fuzz``. Exit
status 1 when any count that must be zero is not.
"""
from __future__ import annotations

import argparse
import collections
import json
import random
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "tests" / "fuzz"), str(HERE.parent)]

from cli_cases import generate, judge, make_scene, regression_cases  # noqa: E402
from cli_worker import run_cli_cases  # noqa: E402
from fuzz_harness import full_disk_trials, kill_trials  # noqa: E402
from loader_worker import fuzz_loaders  # noqa: E402
from nasty_projects import mutate_document, nasty_projects  # noqa: E402
from seeds import make_seeds  # noqa: E402

MUST_BE_ZERO = ("crashes", "hangs", "internal_errors", "escaped", "bad_accepted", "unnamed", "many_lines",
                "unsaveable", "lost_backups", "leftover_temps", "regressions_failed", "over_memory")
MEMORY_LIMIT_MB = 1536  # the peak memory of any input under 100 MB
REAL_DATA = HERE.parents[1] / "shared" / "data"  # beside the repository (its bounded matches; skipped if absent)


def run_cli(count: int, folder: Path, seed: int) -> dict:
    scene = make_scene(folder / "scene")
    named = regression_cases(scene, folder / "regressions", REAL_DATA)
    cases = generate(scene, folder / "cli_cases", count, seed) + [(argv, expect, names)
                                                                   for _, argv, expect, names in named]
    results, memory = run_cli_cases([argv for argv, _, _ in cases], folder)
    verdicts = [judge(case, result) for case, result in zip(cases, results)]
    counts = collections.Counter(verdicts[:-len(named)])
    failed = [(name, verdict, result["stderr"][:200]) for (name, *_), verdict, result in
              zip(named, verdicts[-len(named):], results[-len(named):]) if verdict != "ok"]
    examples = [(" ".join(case[0])[:160], result["code"], result["stderr"][:200])
                for case, result, verdict in zip(cases, results, verdicts) if verdict != "ok"][:5]
    return {"cases": len(cases), "crashes": counts["crash"], "hangs": counts["hang"],
            "internal_errors": counts["internal_error"], "escaped": counts["escaped"],
            "bad_accepted": counts["bad_accepted"], "unnamed": counts["unnamed"],
            "many_lines": counts["many_lines"], "regressions": len(named), "regressions_failed": len(failed),
            "peak_mb": memory["peak_mb"], "slowest_s": max((r.get("seconds", 0.0) for r in results), default=0.0),
            "examples": examples + failed}


def run_projects(count: int, folder: Path, seed: int) -> dict:
    seeds = make_seeds(folder / "project_seeds")
    bad = []
    for name, text in nasty_projects():
        path = folder / f"nasty_{name}.fluoro"
        path.write_text(text, encoding="utf-8")
        bad.append(path)
    rng = random.Random(seed)
    structured = []  # half the cases: JSON-level mutations (values, deletions, repeats)
    for k in range((count - len(bad)) // 2):
        source = seeds["project"][k % len(seeds["project"])]
        path = folder / f"structured_{k}.fluoro"
        path.write_text(json.dumps(mutate_document(json.loads(source.read_text()), rng)))
        structured.append(path)
    per_seed = max(1, (count - len(bad) - len(structured)) // len(seeds["project"]))
    cases = folder / "project_cases"
    cases.mkdir()
    counts = fuzz_loaders({"project": seeds["project"]}, cases, per_seed, seed, bad={"project": bad})
    more = fuzz_loaders({"project": []}, cases, 0, seed, bad={"project": structured})  # may be valid: not "bad"
    more["bad_accepted"] = 0
    for key in ("cases", "accepted", "refused", "escaped", "unsaveable", "crashes", "hangs", "unnamed"):
        counts[key] += more[key]
    counts["examples"] += [e for e in more["examples"] if e["outcome"] != "accepted"]
    return _loader_counts(counts)


def run_loaders(per_seed: int, folder: Path, seed: int) -> dict:
    seeds = make_seeds(folder / "seeds")
    seeds.pop("project")
    cases = folder / "loader_cases"
    cases.mkdir()
    return _loader_counts(fuzz_loaders(seeds, cases, per_seed, seed))


def _loader_counts(counts: dict) -> dict:
    return {"cases": counts["cases"], "crashes": counts["crashes"], "hangs": counts["hangs"],
            "escaped": counts["escaped"], "bad_accepted": counts["bad_accepted"], "unnamed": counts["unnamed"],
            "unsaveable": counts["unsaveable"], "accepted": counts["accepted"], "refused": counts["refused"],
            "examples": counts["examples"][:5]}


def run_kills(trials: int, folder: Path, seed: int) -> dict:
    counts = kill_trials(folder, trials, seed)
    return {"cases": counts["trials"], "lost_backups": counts["lost_or_truncated_project"] +
            counts["lost_or_truncated_backup"], "leftover_temps": counts["leftover_temps_after_next_save"],
            "temps_left_by_kills (removed by the next save)": counts["temps_left_by_kills"]}


def run_full_disk(trials: int, folder: Path) -> dict:
    limits = [1, 4096, 100_000, 300_000, 350_000, 400_000][:max(1, trials)]
    counts = full_disk_trials(folder, limits)
    return {"cases": counts["trials"], "lost_backups": counts["lost_or_truncated_project"] +
            counts["lost_or_truncated_backup"], "leftover_temps": counts["leftover_temps"],
            "unnamed": counts["unclear_messages"], "bad_accepted": counts["accepted"]}


def make_large(folder: Path) -> None:
    """Write the inputs of ``run_large`` into ``folder``."""
    import numpy as np
    import pyvista as pv

    sys.path.insert(0, str(HERE.parent / "benchmarks"))
    from bench_project import session

    from fluorogui.core.projection.geometry import View
    from fluorogui.core.records import ImageSequence, ModelEntry, OutlineRecord, PoseRecord, Project
    from fluorogui.io.project.document import save_project

    save_project(session(folder, 1400, 400), folder / "long.fluoro")
    views = [View.looking_at((0, -1000, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(1024, 1024), pitch=0.4,
                             name="cam1"),
             View.looking_at((800, -600, 0), (0, 0, 0), (0, 0, 1), 1150, image_size=(1024, 1024), pitch=0.4,
                             name="cam2")]
    frames, components = list(range(85_000)), ("femoral", "tibial")
    tiny = Project(views, [ImageSequence([folder / f"c{k}" / f"{i}.tif" for i in frames]) for k in range(2)], frames,
                   [ModelEntry(c, folder / f"{c}.stl") for c in components],
                   {(f, v, c): OutlineRecord(np.arange(8.0).reshape(4, 2)) for f in frames for v in range(2)
                    for c in components},
                   {(f, c): PoseRecord(np.zeros(6)) for f in frames for c in components}, {})
    save_project(tiny, folder / "small_outlines.fluoro")
    keys = ",".join(f'"k{i}":0' for i in range(7_000_000))  # an object of 7 million members, 90 MB
    (folder / "keys.fluoro").write_text('{"format": "fluorogui-project", "schema_version": 6, "settings": {"gui": {'
                                        + keys + "}}}")
    triangles = 1_800_000
    rng = np.random.default_rng(0)
    stl = np.zeros(triangles, dtype=[("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
    stl["corners"] = rng.uniform(-40, 40, (triangles, 3, 3))
    with open(folder / "large.stl", "wb") as handle:
        handle.write(b"\0" * 80 + np.uint32(triangles).tobytes() + stl.tobytes())
    # 250,000 triangles (the most matched without simplifying), closed
    ball = pv.Sphere(radius=20.0, theta_resolution=500, phi_resolution=252)
    ball.save(folder / "ball_250k.stl")
    with open(folder / "large.csv", "w") as handle:
        handle.write("u,v\n" + "512.1234,300.5678\n" * 4_800_000)
    (folder / "large.png").write_bytes(b"\x89PNG\r\n\x1a\n" + rng.bytes(90_000_000))


def run_large(folder: Path) -> dict:
    """Inputs near 100 MB, each loaded in its own child, and ``fluorogui match`` with the
    large mesh and the largest accepted one; the peak memory per input."""
    import os
    import subprocess

    # written by a child, so that this process stays small (a child's peak memory counts
    # what it shares with its parent at the fork)
    subprocess.run([sys.executable, __file__, "--make-large", str(folder)], check=True)
    scene = make_scene(folder / "scene")
    env = dict(os.environ, PYTHONPATH=str(HERE.parent), FLUOROGUI_DATA_DIR=str(folder / "appdata"))
    loads = [("project", "long.fluoro"), ("project", "small_outlines.fluoro"), ("project", "keys.fluoro"),
             ("mesh", "large.stl"), ("outline", "large.csv"), ("image", "large.png")]
    runs = [([sys.executable, str(HERE.parent / "tests" / "fuzz" / "loader_worker.py"), loader, str(folder / name)],
             f"load {name} ({(folder / name).stat().st_size / 1e6:.0f} MB)") for loader, name in loads]
    for mesh in ("large.stl", "ball_250k.stl"):
        argv = ["match", "--camera", str(scene["cam0"]), "--camera", str(scene["cam1"]), "--image", str(scene["img0"]),
                "--image", str(scene["img1"]), "--model", str(folder / mesh), "--outline", str(scene["outline0"]),
                "--outline", str(scene["outline1"]), "--start", "0", "0", "0", "0", "0", "0"]
        runs.append(([sys.executable, "-m", "fluorogui", *argv],
                     f"fluorogui match --model {mesh} ({(folder / mesh).stat().st_size / 1e6:.0f} MB)"))
    counts = {"cases": 0, "crashes": 0, "escaped": 0, "over_memory": 0, "peak_mb": 0.0, "per_input": {}}
    for argv, label in runs:
        child = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        out, err = child.stdout.read(), child.stderr.read()
        _, status, usage = os.wait4(child.pid, 0)
        peak = usage.ru_maxrss / 1024.0
        rows = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
        code = os.waitstatus_to_exitcode(status)
        if argv[1] == "-m":  # a command line: exit 0, 2 or 3 with its line(s) on stderr
            outcome = {0: "matched", 2: "refused", 3: "not converged"}.get(code, f"exit {code}")
            counts["crashes"] += code < 0
            counts["escaped"] += code not in (0, 2, 3) and code >= 0
            detail = err.strip().splitlines()[-1][:160] if err.strip() else ""
        else:
            outcome = rows[0]["outcome"] if rows else "crash"
            counts["crashes"] += not rows
            counts["escaped"] += bool(rows) and rows[0]["outcome"] == "escaped"
            detail = rows[0]["message"][:160] if rows else ""
        counts["cases"] += 1
        counts["over_memory"] += peak > MEMORY_LIMIT_MB
        counts["peak_mb"] = max(counts["peak_mb"], peak)
        counts["per_input"][label] = f"{outcome}, {peak:.0f} MB" + (f" ({detail})" if detail else "")
    return counts


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cli", type=int, default=1000)
    parser.add_argument("--projects", type=int, default=500)
    parser.add_argument("--loaders", type=int, default=40, help="mutations per seed file")
    parser.add_argument("--kills", type=int, default=100)
    parser.add_argument("--full-disk", type=int, default=4)
    parser.add_argument("--large", action="store_true", help="also load inputs near 100 MB (peak memory)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    report = {}
    with tempfile.TemporaryDirectory(prefix="fluorogui-fuzz-") as tmp:
        tmp = Path(tmp)
        steps = [("command line", args.cli, lambda d: run_cli(args.cli, d, args.seed)),
                 ("project files", args.projects, lambda d: run_projects(args.projects, d, args.seed)),
                 ("other loaders", args.loaders, lambda d: run_loaders(args.loaders, d, args.seed)),
                 ("kills during save", args.kills, lambda d: run_kills(args.kills, d, args.seed)),
                 ("full-disk saves", args.full_disk, lambda d: run_full_disk(args.full_disk, d)),
                 ("large inputs", int(args.large), run_large)]
        for name, wanted, step in steps:
            if wanted <= 0:
                continue
            folder = tmp / name.replace(" ", "_")
            folder.mkdir()
            started = time.monotonic()
            report[name] = step(folder) | {"seconds": round(time.monotonic() - started, 1)}
            print(f"{name}: " + ", ".join(f"{k} {v}" for k, v in report[name].items()
                                          if k not in ("examples", "per_input")), flush=True)
            for label, outcome in report[name].get("per_input", {}).items():
                print(f"    {label}: {outcome}")
            for example in report[name].get("examples", []):
                print(f"    {example}")
    import resource

    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    totals = {key: sum(r.get(key, 0) for r in report.values()) for key in MUST_BE_ZERO}
    print("\ntotal: " + ", ".join(f"{k} {v}" for k, v in totals.items()) + f"; peak memory of any worker {peak:.0f} MB")
    if args.json:
        print(json.dumps({"report": report, "totals": totals, "peak_mb": peak}, default=str))
    return 1 if any(totals.values()) or peak > MEMORY_LIMIT_MB else 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["--make-large"]:
        sys.exit(make_large(Path(sys.argv[2])))
    sys.exit(main())
