"""The long fuzz run of issue 11: throw broken inputs at every loader, the command line and
the project saves, and print the counts that must all be zero.

    python tools/fuzz.py --cli 1000 --projects 500 --loaders 40 --kills 100 --full-disk 4 --large

``--cli``: command lines (bad option values, missing / folder / FIFO / empty / junk /
truncated / mutated input files) run through ``fluorogui.cli.main`` in worker processes;
``--projects``: mutated and hand-made nasty project files through ``load_project`` (and an
accepted one must save and reopen unchanged); ``--loaders``: mutations per seed file of
every other loader (calibrations of each format, images, meshes, outlines, pairs, poses);
``--kills``: a saving child killed at random moments; ``--full-disk``: saves under
``RLIMIT_FSIZE`` limits; ``--large``: inputs near 100 MB, each in its own process, for
the peak memory. The quick versions of these run in ``tests/fuzz``. Exit status 1
when any count that must be zero is not.
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

from cli_cases import generate, judge, make_scene  # noqa: E402
from cli_worker import run_cli_cases  # noqa: E402
from fuzz_harness import full_disk_trials, kill_trials  # noqa: E402
from loader_worker import fuzz_loaders  # noqa: E402
from nasty_projects import mutate_document, nasty_projects  # noqa: E402
from seeds import make_seeds  # noqa: E402

MUST_BE_ZERO = ("crashes", "hangs", "internal_errors", "escaped", "bad_accepted", "unnamed", "many_lines",
                "unsaveable", "lost_backups", "leftover_temps")


def run_cli(count: int, folder: Path, seed: int) -> dict:
    scene = make_scene(folder / "scene")
    cases = generate(scene, folder / "cli_cases", count, seed)
    results, memory = run_cli_cases([argv for argv, _, _ in cases], folder)
    verdicts = collections.Counter(judge(case, result) for case, result in zip(cases, results))
    examples = [(" ".join(case[0])[:160], result["code"], result["stderr"][:200])
                for case, result in zip(cases, results) if judge(case, result) != "ok"][:5]
    return {"cases": len(cases), "crashes": verdicts["crash"], "hangs": verdicts["hang"],
            "internal_errors": verdicts["internal_error"], "escaped": verdicts["escaped"],
            "bad_accepted": verdicts["bad_accepted"], "unnamed": verdicts["unnamed"],
            "many_lines": verdicts["many_lines"], "peak_mb": memory["peak_mb"], "examples": examples}


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

    sys.path.insert(0, str(HERE))
    from bench_project import session

    from fluorogui.io.project.document import save_project

    save_project(session(folder, 1400, 400), folder / "long.fluoro")
    triangles = 1_800_000
    rng = np.random.default_rng(0)
    stl = np.zeros(triangles, dtype=[("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
    stl["corners"] = rng.uniform(-40, 40, (triangles, 3, 3))
    with open(folder / "large.stl", "wb") as handle:
        handle.write(b"\0" * 80 + np.uint32(triangles).tobytes() + stl.tobytes())
    with open(folder / "large.csv", "w") as handle:
        handle.write("u,v\n" + "512.1234,300.5678\n" * 4_800_000)
    (folder / "large.png").write_bytes(b"\x89PNG\r\n\x1a\n" + rng.bytes(90_000_000))


def run_large(folder: Path) -> dict:
    """Inputs near 100 MB (a long project, a large binary STL, a large outline CSV, a large
    junk PNG, a 1-GB-claiming PLY): each loaded in its own child; peak memory per input."""
    import os
    import subprocess

    # written by a child, so that this process stays small (a child's peak memory counts
    # what it shares with its parent at the fork)
    subprocess.run([sys.executable, __file__, "--make-large", str(folder)], check=True)
    files = {"project": folder / "long.fluoro", "mesh": folder / "large.stl", "outline": folder / "large.csv",
             "image": folder / "large.png"}
    counts = {"cases": 0, "crashes": 0, "escaped": 0, "peak_mb": 0.0, "per_input": {}}
    env = dict(os.environ, PYTHONPATH=str(HERE.parent))
    for loader, path in files.items():
        child = subprocess.Popen([sys.executable, str(HERE.parent / "tests" / "fuzz" / "loader_worker.py"), loader,
                                  str(path)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)
        out = child.stdout.read()
        _, status, usage = os.wait4(child.pid, 0)
        child.returncode = status
        peak = usage.ru_maxrss / 1024.0
        rows = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
        counts["cases"] += 1
        counts["crashes"] += not rows
        counts["escaped"] += bool(rows) and rows[0]["outcome"] == "escaped"
        counts["peak_mb"] = max(counts["peak_mb"], peak)
        outcome = rows[0]["outcome"] if rows else "crash"
        counts["per_input"][f"{path.name} ({path.stat().st_size / 1e6:.0f} MB)"] = f"{outcome}, {peak:.0f} MB"
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
            print(f"{name}: " + ", ".join(f"{k} {v}" for k, v in report[name].items() if k != "examples"),
                  flush=True)
            for example in report[name].get("examples", []):
                print(f"    {example}")
    import resource

    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    totals = {key: sum(r.get(key, 0) for r in report.values()) for key in MUST_BE_ZERO}
    print("\ntotal: " + ", ".join(f"{k} {v}" for k, v in totals.items()) + f"; peak memory of any worker {peak:.0f} MB")
    if args.json:
        print(json.dumps({"report": report, "totals": totals, "peak_mb": peak}, default=str))
    return 1 if any(totals.values()) or peak > 2048 else 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["--make-large"]:
        sys.exit(make_large(Path(sys.argv[2])))
    sys.exit(main())
