"""Developer benchmark: the exact silhouette per call, on the calls the matcher really makes.

``record`` runs ``bench_speed.py``'s sections (default ``real match``) with every
``mesh_silhouette`` call written down (mesh, pose, view, scale, spacing, in call order);
``replay`` runs the written calls again through this checkout's silhouette, on fresh meshes
so that the kept facing state builds up as it did, and prints the CPU milliseconds per call
for each mesh. With ``--against REV`` it runs the silhouette module of git revision REV on
the same calls, interleaved call by call (so a changing machine load hits both alike), and
counts the calls whose outputs differ in any bit.

Usage: .venv/bin/python benchmarks/bench_silhouette.py record CALLS.pkl [real] [match]
       .venv/bin/python benchmarks/bench_silhouette.py replay CALLS.pkl [--against REV] [--repeat N]
"""
from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import pickle
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

CALLERS = ["fluorogui.core.matching.loop", "fluorogui.core.matching.quality", "fluorogui.core.matching.fast",
           "fluorogui.core.outlines.rim", "fluorogui.simulation.protocols"]


def record(out: Path, sections: list[str]) -> None:
    from fluorogui.core.projection import silhouette

    plain = silhouette.mesh_silhouette
    calls, meshes, views, lock = [], {}, {}, threading.Lock()

    def written(mesh, R, t, view, *, scale=2.0, spacing_px=None):
        with lock:
            meshes.setdefault(id(mesh), (mesh.vertices, mesh.faces))
            views.setdefault(id(view), view)
            calls.append((id(mesh), np.array(R, float), np.array(t, float), id(view), scale, spacing_px))
        return plain(mesh, R, t, view, scale=scale, spacing_px=spacing_px)

    for name in CALLERS:
        importlib.import_module(name).mesh_silhouette = written
    silhouette.mesh_silhouette = written
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_speed

    bench_speed.main(sections or ["real", "match"])
    out.write_bytes(pickle.dumps({"calls": calls, "meshes": meshes, "views": views}))
    print(f"{len(calls)} calls of {len(meshes)} meshes written to {out}")


def _module_at(rev: str):
    """The silhouette module of git revision ``rev`` (its imports resolve to this checkout)."""
    source = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:fluorogui/core/projection/silhouette.py"],
                            check=True, capture_output=True, text=True).stdout
    path = Path(tempfile.mkdtemp(prefix="bench-silhouette-")) / "silhouette_at_rev.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("silhouette_at_rev", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def replay(path: Path, against: str | None, repeat: int) -> None:
    from fluorogui.core.projection import silhouette
    from fluorogui.core.projection.mesh import prepare_mesh

    data = pickle.loads(path.read_bytes())
    modules = {"this": silhouette}
    if against:
        modules = {against: _module_at(against), "this": silhouette}
    print("replay: load average " + " ".join(f"{v:.1f}" for v in os.getloadavg()) + f" on {os.cpu_count()} cores")
    for _ in range(repeat):
        meshes = {name: {k: prepare_mesh(*m) for k, m in data["meshes"].items()} for name in modules}
        seconds, differ = {}, 0
        for key, R, t, view_key, scale, spacing in data["calls"]:
            out = {}
            for name, module in modules.items():
                mesh = meshes[name][key]
                c0 = time.process_time()
                out[name] = module.mesh_silhouette(mesh, R, t, data["views"][view_key], scale=scale,
                                                   spacing_px=spacing)
                seconds.setdefault((f"{len(mesh.vertices)} vertices", name), []).append(time.process_time() - c0)
            if against:
                a, b = out.values()
                differ += not all(np.array_equal(getattr(a, f), getattr(b, f))
                                  for f in ("points_px", "model_points", "segments_px"))
        for mesh_name in sorted({k[0] for k in seconds}):
            line = ", ".join(f"{name} {1e3 * np.mean(seconds[mesh_name, name]):.3f} ms" for name in modules)
            print(f"  mesh of {mesh_name}: {len(seconds[mesh_name, 'this'])} calls, CPU per call: {line}")
        total = ", ".join(f"{name} {sum(sum(v) for k, v in seconds.items() if k[1] == name):.3f} s" for name in modules)
        print(f"  all {len(data['calls'])} calls: {total}" + (f"; {differ} differ in any bit" if against else ""))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record", help="run bench_speed's sections and write down every silhouette call")
    rec.add_argument("calls", type=Path)
    rec.add_argument("sections", nargs="*", choices=["real", "match"])
    rep = sub.add_parser("replay", help="run the written calls again and time them")
    rep.add_argument("calls", type=Path)
    rep.add_argument("--against", help="a git revision whose silhouette module runs the same calls")
    rep.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args(argv)
    if args.command == "record":
        record(args.calls, args.sections)
    else:
        replay(args.calls, args.against, args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
