"""``fluorogui bench``: time matches of both methods on rendered images of implant meshes."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fluorogui.cli.common import OUTLINE_POINTS_RANGE, POINTS_RANGE, SEED_RANGE, STARTS_RANGE, UsageError, int_in
from fluorogui.cli.inputs import load_model


def add_parser(sub):
    b = sub.add_parser("bench", help="time matches of both methods on the real implant meshes")
    b.add_argument("--model", action="append", metavar="MESH", help="default: the meshes in ../shared/data")
    b.add_argument("--method", nargs="+", choices=["fast", "paper"], default=["fast", "paper"])
    b.add_argument("--starts", type=int_in(*STARTS_RANGE), default=10)
    b.add_argument("--points", type=int_in(*POINTS_RANGE), default=15000)
    b.add_argument("--outline-points", type=int_in(*OUTLINE_POINTS_RANGE), default=60)
    b.add_argument("--seed", type=int_in(*SEED_RANGE), default=0)
    b.add_argument("--json", action="store_true")
    return b


def default_bench_models():
    data = Path(__file__).resolve().parents[1].parent / "shared" / "data"
    found = sorted(data.glob("*/models/*.stl")) + sorted(data.glob("single-plane-tka/*.stl"))
    return [str(p) for p in found]


def run(args) -> int:
    from fluorogui.core.matching.problem import MatchSettings
    from fluorogui.simulation.protocols import idealized_case

    models = args.model or default_bench_models()
    if not models:
        raise UsageError("fluorogui: no meshes given and none found in ../shared/data; use --model")
    print(f"bench: {args.starts} starts within ±20 mm / ±20 deg per model, {args.points} model points (paper), "
          f"{args.outline_points} outline points, rendered images at 45 deg flexion\n")
    print(f"{'model':<28}{'method':<8}{'median s':>10}{'min s':>9}{'max s':>9}{'ms/call':>9}{'calls':>7}{'conv':>6}")
    payload = []
    for model_path in models:
        mesh = load_model(model_path)
        for method in args.method:
            settings = MatchSettings(method=method, model_points=args.points, outline_points=args.outline_points)
            case = idealized_case(mesh.vertices, mesh.faces, 45.0, settings, args.starts, args.seed)
            secs = np.array([r.seconds for r in case.results])
            calls = np.array([r.calls for r in case.results])
            per_call = 1000.0 * secs / np.maximum(calls, 1)
            conv = sum(r.converged for r in case.results)
            print(f"{Path(model_path).name:<28}{method:<8}{np.median(secs):>10.3f}{secs.min():>9.3f}{secs.max():>9.3f}"
                  f"{np.median(per_call):>9.2f}{np.median(calls):>7.0f}{conv:>4}/{len(secs)}")
            payload.append({"model": model_path, "method": method, "median_s": float(np.median(secs)),
                            "min_s": float(secs.min()), "max_s": float(secs.max()),
                            "median_ms_per_call": float(np.median(per_call)), "median_calls": float(np.median(calls)),
                            "converged": int(conv), "runs": len(secs),
                            "max_abs_error": np.abs(case.errors).max(0).tolist()})
    if args.json:
        print(json.dumps(payload))
    return 0
