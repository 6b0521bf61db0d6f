"""Developer benchmark: issue 46's speed numbers, with the poses to compare versions by.

Sections (all by default, or name some):

* ``match``: ``fluorogui match --json`` (in this process, through the command line's own
  ``main``) on a generated two-view femoral scene (the demo's procedural femoral component
  at 45 deg flexion, dual orthogonal views, rendered images, as ``tests/cli/test_cli.py``)
  from three starts 2 mm / 2 deg off, against a paper-faithful BFGS baseline in the same
  run (``core.matching.paper``: a 15k-point cloud, its grid outline, 60 outline points,
  finite-difference BFGS) on the same images' outlines (Canny, sub-pixel, chosen along the
  true pose) from the same starts. Reports each method's median seconds (``seconds`` of the
  JSON for match), the ratio (target >= 50) and the poses (target <= 0.2 s).
* ``real``: the 33 pairs of ../shared/data/biplane-tka, both components, tracked from
  nothing (``Session.track``) with ``--workers`` workers: wall and CPU seconds (target
  <= 15 s wall), wall per pair over the whole run (target <= 0.2 s), the consecutive pairs'
  median (frames 51-69, both components' own seconds; target <= 0.1 s), the wall and CPU
  seconds by kind of frame (the first, flagged ones, jumps, consecutive ones; one worker)
  and every pose. With workers, the workers' CPU is reported beside this process's.
* ``workers``: the real section once per worker count of ``--compare`` (default 1 and 2),
  the wall times side by side.

Machine load matters on a shared machine: each section prints ``os.getloadavg()`` before it.
``--json OUT`` writes the numbers and every pose; ``--poses-against OLD.json`` compares this
run's poses with an earlier run's (largest difference, mm and deg, per section).

Usage: .venv/bin/python benchmarks/bench_speed.py [match] [real] [workers] [--workers N]
           [--compare 1 2] [--repeat N] [--json OUT] [--poses-against OLD.json]
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fluorogui import Session  # noqa: E402
from fluorogui.core.projection.pose import pose_error  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
OFFSETS = np.array([[2, -2, 2, 2, -2, 2], [-2, 2, -2, -2, 2, -2], [2, 2, -2, 2, 2, -2]], dtype=float)


def _load() -> str:
    return "load average " + " ".join(f"{v:.1f}" for v in os.getloadavg()) + f" on {os.cpu_count()} cores"


def generated_scene(folder: Path) -> dict:
    """Two calibrations, two rendered images and a mesh file of the demo's femoral
    component at 45 deg flexion (the command-line tests' scene)."""
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
    views = dual_orthogonal_views()
    rng = np.random.default_rng(0)
    world = transform_points(truth, mesh.vertices)
    scene = {"cams": [], "images": [], "truth": truth, "views": views, "mesh": mesh}
    for k, view in enumerate(views):
        cam, img = folder / f"cam{k + 1}.json", folder / f"img{k + 1}.png"
        save_view_json(view, cam)
        write_image(img, render_fluoro(view, [(world, mesh.faces)], rng), bits=16)
        scene["cams"].append(str(cam))
        scene["images"].append(str(img))
    model = folder / "femur.stl"
    pv.PolyData(v, np.column_stack([np.full(len(f), 3), f]).ravel()).save(str(model))
    scene["model"] = str(model)
    return scene


def _cli_match(scene: dict, start) -> dict:
    from fluorogui.cli.entry import main

    argv = ["match"]
    for cam in scene["cams"]:
        argv += ["--camera", cam]
    for image in scene["images"]:
        argv += ["--image", image]
    argv += ["--model", scene["model"], "--start", *[repr(float(x)) for x in start], "--json"]
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        main(argv)
    return json.loads(buffer.getvalue().strip().splitlines()[-1])


def _paper_baseline(scene: dict, start):
    """The paper's method (BFGS, finite differences, point-cloud outline) on the scene's own
    outlines, segmented from its images along the true pose."""
    from fluorogui.core.matching.matcher import match
    from fluorogui.core.matching.problem import MatchProblem, MatchSettings
    from fluorogui.io.images import read_image
    from fluorogui.simulation.protocols import outlines_from_images

    if "splines" not in scene:
        images = [read_image(p) for p in scene["images"]]
        scene["splines"] = outlines_from_images(images, scene["views"], scene["mesh"], scene["truth"])
    problem = MatchProblem(scene["mesh"], scene["views"], scene["splines"])
    return match(problem, start, MatchSettings(method="paper", outline_points=60, model_points=15000))


def bench_match(args) -> dict:
    print(f"match: {_load()}")
    scene = generated_scene(Path(tempfile.mkdtemp(prefix="bench-speed-")))
    truth = scene["truth"]
    fast, paper, poses = [], [], []
    for _ in range(args.repeat):
        for offset in OFFSETS:
            out = _cli_match(scene, truth + offset)
            fast.append(out["seconds"])
            poses.append(out["pose"])
            err = pose_error(np.array(out["pose"]), truth)
            print(f"  fluorogui match from {offset.tolist()}: {out['seconds']:.3f} s, {out['calls']} calls, "
                  f"{out['status']}, error {np.abs(err[:3]).max():.4f} mm / {np.abs(err[3:]).max():.4f} deg")
    for offset in OFFSETS:
        result = _paper_baseline(scene, truth + offset)
        paper.append(result.seconds)
        err = pose_error(result.pose, truth)
        print(f"  paper BFGS from {offset.tolist()}: {result.seconds:.3f} s, {result.calls} calls, error "
              f"{np.abs(err[:3]).max():.4f} mm / {np.abs(err[3:]).max():.4f} deg")
    m_fast, m_paper = float(np.median(fast)), float(np.median(paper))
    print(f"match: median {m_fast:.3f} s (target <= 0.2 s), paper BFGS baseline median {m_paper:.3f} s: "
          f"{m_paper / m_fast:.0f}x faster (target >= 50x)\n")
    return {"match_median_s": m_fast, "match_seconds": fast, "paper_median_s": m_paper, "paper_seconds": paper,
            "speedup": m_paper / m_fast, "poses": poses, "load": os.getloadavg()}


def track_real(workers: int) -> dict:
    """The 33 real pairs tracked from nothing, both components, with ``workers`` workers."""
    from fluorogui.io.importer import import_folder
    from fluorogui.io.project.document import save_project

    print(f"real, {workers} worker(s): {_load()}")
    path = Path(tempfile.mkdtemp(prefix="bench-speed-real-")) / "real.fluoro"
    save_project(import_folder(DATA / "biplane-tka"), path)
    session = Session.open(path)
    t0, c0 = time.perf_counter(), time.process_time()
    children0 = _children_cpu()
    costs: dict[int, tuple[float, float]] = {}  # frame -> (wall, cpu) of its work, one worker only
    last = [t0, c0]

    def progress(done, total, frame, text):
        now, cpu_now = time.perf_counter(), time.process_time()
        costs[frame] = (now - last[0], cpu_now - last[1])
        last[:] = [now, cpu_now]

    rows = list(session.track(None, components="both", workers=workers,
                              progress=progress if workers == 1 else None))  # (workers: CPU in them)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0  # (cpu: this process only)
    children = _children_cpu() - children0  # worker processes, once they have ended
    n = len(session.frames)
    seconds = {(r.frame, r.component): r.seconds for r in rows}
    pairs = [seconds[(f, "femoral")] + seconds[(f, "tibial")] for f in range(51, 70)
             if (f, "femoral") in seconds and (f, "tibial") in seconds]
    flagged = [f"{r.frame} {r.component}: {r.reason}" for r in rows if r.status != "matched"]
    out = {"workers": workers, "wall_s": wall, "cpu_s": cpu, "children_cpu_s": children, "pairs": n,
           "wall_per_pair_s": wall / n,
           "consecutive_pair_median_s": float(np.median(pairs)), "flagged": flagged,
           "by_kind": _by_kind(session.frames, costs, rows),
           "poses": {f"{r.frame} {r.component}": None if r.pose is None else [float(v) for v in r.pose]
                     for r in rows},
           "statuses": {f"{r.frame} {r.component}": str(r.status) for r in rows}}
    print(f"  {n} pairs from nothing: {wall:.1f} s wall (target <= 15 s), {wall / n:.3f} s per pair over the "
          f"whole run (target <= 0.2 s), this process's CPU {cpu:.1f} s"
          + (f" and its workers' {children:.1f} s" if workers > 1 else "")
          + f"; consecutive pairs 51-69 median {out['consecutive_pair_median_s']:.3f} s (target <= 0.1 s); "
          f"{len(flagged)} flagged")
    for kind, (count, w, c) in out["by_kind"].items():
        print(f"    {kind}: {count} frame(s), {w:.1f} s wall, {c:.1f} CPU-s")
    for line in flagged:
        print("    " + line)
    return out


def _children_cpu() -> float:
    """CPU seconds of this process's ended child processes (the workers)."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _by_kind(frames, costs: dict, rows) -> dict[str, tuple[int, float, float]]:
    """Where the run's time went, by kind of frame: the first (find implants, the rim
    judgement), flagged ones (every recovery start tried), jumps (more than
    ``NEAR_FIRST_GAP`` frame numbers after the one before: searches first) and
    consecutive ones: (frames, wall s, CPU-s) each, from the work between ``progress``
    calls (a frame's own, and the frames it tracked back into). Empty with workers."""
    from fluorogui.workflow.framematch import NEAR_FIRST_GAP

    if not costs:
        return {}
    flagged = {r.frame for r in rows if r.status != "matched"}
    kinds: dict[str, list] = {k: [0, 0.0, 0.0] for k in ("first frame", "flagged", "jumps", "consecutive")}
    for i, f in enumerate(frames):
        if f not in costs:
            continue
        kind = ("first frame" if i == 0 else "flagged" if f in flagged
                else "jumps" if f - frames[i - 1] > NEAR_FIRST_GAP else "consecutive")
        kinds[kind][0] += 1
        kinds[kind][1] += costs[f][0]
        kinds[kind][2] += costs[f][1]
    return {k: tuple(v) for k, v in kinds.items() if v[0]}


def bench_real(args) -> dict:
    return track_real(args.workers)


def bench_workers(args) -> dict:
    runs = {str(w): track_real(w) for w in args.compare}
    print("workers: " + ", ".join(f"{w}: {r['wall_s']:.1f} s wall, {r['cpu_s'] + r['children_cpu_s']:.1f} CPU-s"
                                  for w, r in runs.items()) + "\n")
    return runs


def _largest_difference(a: dict, b: dict) -> tuple[float, float]:
    mm = deg = 0.0
    for key, pose in a.items():
        other = b.get(key)
        if pose is None or other is None:
            continue
        d = np.abs(np.asarray(pose) - np.asarray(other))
        mm, deg = max(mm, float(d[:3].max())), max(deg, float(d[3:].max()))
    return mm, deg


def compare(now: dict, old: dict) -> None:
    """This run's poses against an earlier run's, per section."""
    for section in ("match", "real"):
        if section in now and section in old:
            a, b = now[section]["poses"], old[section]["poses"]
            if isinstance(a, list):
                a, b = dict(enumerate(a)), dict(enumerate(b))
            mm, deg = _largest_difference(a, b)
            print(f"{section}: poses against the earlier run: largest difference {mm:.6f} mm / {deg:.6f} deg")
        if section == "real" and section in now and section in old:
            changed = [k for k, s in now[section]["statuses"].items() if old[section]["statuses"].get(k) != s]
            print(f"real: statuses changed: {changed or 'none'}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sections", nargs="*", choices=["match", "real", "workers"], default=[])
    ap.add_argument("--workers", type=int, default=1, help="workers for the real section (default 1)")
    ap.add_argument("--compare", type=int, nargs="+", default=[1, 2], help="worker counts of the workers section")
    ap.add_argument("--repeat", type=int, default=1, help="match: times to run the three starts")
    ap.add_argument("--json", type=Path, help="write the numbers and poses here")
    ap.add_argument("--poses-against", type=Path, help="an earlier run's --json: compare the poses")
    args = ap.parse_args(argv)
    sections = args.sections or ["match", "real", "workers"]
    if any(s in sections for s in ("real", "workers")) and not DATA.is_dir():
        print(f"bench_speed: {DATA} not found; only the match section can run", file=sys.stderr)
        sections = [s for s in sections if s == "match"]
    out = {s: globals()[f"bench_{s}"](args) for s in sections}
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    if args.poses_against:
        compare(out, json.loads(args.poses_against.read_text()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
