"""``fluorogui bench``: time matches of both methods on rendered images of implant meshes.

With ``--model`` it times the given meshes; without, the built-in demo's procedural
femoral and tibial components (``fluorogui.simulation.phantoms``), so the command works
on an installed package with no data beside it. The benchmark numbers in the docs come
from the real implant meshes of the biplane data set, passed with ``--model``."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fluorogui.cli.common import OUTLINE_POINTS_RANGE, POINTS_RANGE, SEED_RANGE, STARTS_RANGE, int_in
from fluorogui.cli.inputs import load_model


def add_parser(sub):
    b = sub.add_parser("bench", help="time matches of both methods on rendered images of implant meshes")
    b.add_argument("--model", action="append", metavar="MESH",
                   help="an implant mesh to time (repeat for more); default: the demo's procedural "
                        "femoral and tibial components")
    b.add_argument("--method", nargs="+", choices=["fast", "paper"], default=["fast", "paper"])
    b.add_argument("--starts", type=int_in(*STARTS_RANGE), default=10)
    b.add_argument("--points", type=int_in(*POINTS_RANGE), default=15000)
    b.add_argument("--outline-points", type=int_in(*OUTLINE_POINTS_RANGE), default=60)
    b.add_argument("--seed", type=int_in(*SEED_RANGE), default=0)
    b.add_argument("--json", action="store_true")
    return b


def demo_models():
    """(name, PreparedMesh) of the demo's procedural components: what ``bench`` times
    when no ``--model`` is given."""
    from fluorogui.core.projection.mesh import prepare_mesh
    from fluorogui.simulation.phantoms import femoral_component_mesh, tibial_component_mesh

    return [("demo femoral component", prepare_mesh(*femoral_component_mesh())),
            ("demo tibial component", prepare_mesh(*tibial_component_mesh()))]


def run(args) -> int:
    from fluorogui.core.matching.problem import MatchSettings
    from fluorogui.simulation.protocols import idealized_case

    if args.model:
        models = [(path, load_model(path)) for path in args.model]
    else:
        models = demo_models()
        print("bench: no --model given: timing the demo's procedural components; pass --model MESH "
              "(STL/PLY/OBJ/VTK, mm) to time your implant meshes")
    print(f"bench: {args.starts} starts within ±20 mm / ±20 deg per model, {args.points} model points (paper), "
          f"{args.outline_points} outline points, rendered images at 45 deg flexion\n")
    print(f"{'model':<28}{'method':<8}{'median s':>10}{'min s':>9}{'max s':>9}{'ms/call':>9}{'calls':>7}{'conv':>6}")
    payload = []
    for model_path, mesh in models:
        for method in args.method:
            settings = MatchSettings(method=method, model_points=args.points, outline_points=args.outline_points)
            case = idealized_case(mesh.vertices, mesh.faces, 45.0, settings, n_starts=args.starts, seed=args.seed)
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
