"""Developer tool: the automatic loop's poses on the real biplane data with and without
the rim refinement (``LoopSettings.rim``), for ``tools/reference_poses.py --poses``.

Each frame of ``tests/data/biplane_reference_poses.csv`` (the matcher's own poses) is
matched again from its listed pose by ``core.matching.loop.segment_and_match``, the other
component masked at its listed pose as tracking does, once with plain outlines and once
with the rim refinement (its rim models fitted on the first frame and kept, as
``FrameMatcher`` keeps them). Prints per frame the objective, the per-view residual and
the rim models, and writes ``<out>/<component>_plain.csv`` and ``<component>_rim.csv``
(the other component's rows copied, for its mask in the reference fit).

Usage: .venv/bin/python tools/rim_real_poses.py [--component femoral|tibial] [--frames 8] [--out DIR]
then:  .venv/bin/python tools/reference_poses.py --frames 8 --components femoral --poses DIR/femoral_rim.csv
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fluorogui.core.matching.loop import LoopSettings, segment_and_match  # noqa: E402
from fluorogui.core.projection.mesh import prepare_mesh  # noqa: E402
from fluorogui.io.calibration import load_view  # noqa: E402
from fluorogui.io.images import read_image  # noqa: E402
from fluorogui.io.meshes.read import load_mesh  # noqa: E402
from fluorogui.io.pose_files import POSE_KEYS  # noqa: E402
from fluorogui.workflow.framematch import occlusion_masks  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "biplane-tka")
    ap.add_argument("--poses", type=Path, default=ROOT / "tests" / "data" / "biplane_reference_poses.csv")
    ap.add_argument("--component", choices=["femoral", "tibial"], default="femoral")
    ap.add_argument("--frames", type=int, default=8, help="the first N frames (0: all)")
    ap.add_argument("--out", type=Path, default=Path("rim_real_poses"))
    args = ap.parse_args(argv)
    data, comp = args.data, args.component
    other = "tibial" if comp == "femoral" else "femoral"
    views = [load_view(data / f"calibration/cam{k}_mayacam2.txt") for k in (1, 2)]
    with open(data / "pairs.csv", newline="") as fh:
        pairs = {int(r["frame"]): (r["cam1"], r["cam2"]) for r in csv.DictReader(fh)}
    with open(args.poses, newline="") as fh:
        listed = {(int(r["frame"]), r["component"]): np.array([float(r[k]) for k in POSE_KEYS])
                  for r in csv.DictReader(fh)}
    mesh = prepare_mesh(*load_mesh(data / f"models/{comp}_component.stl"))
    other_mesh = prepare_mesh(*load_mesh(data / f"models/{other}_component.stl"))
    frames = sorted(f for f, c in listed if c == comp)
    frames = frames[:args.frames] if args.frames else frames
    args.out.mkdir(parents=True, exist_ok=True)
    for rim in (False, True):
        models, rows = [None] * len(views), []
        for f in frames:
            images = [read_image(data / p) for p in pairs[f]]
            occluded = (occlusion_masks(views, [(other_mesh, listed[f, other])], listed[f, comp], mesh)
                        if (f, other) in listed else None)
            result = segment_and_match(images, views, mesh, listed[f, comp], loop=LoopSettings(rim=rim),
                                       occluded=occluded, rim_models=models)
            print(f"{'rim' if rim else 'plain'} frame {f}: objective {result.objective_mm:.4f} mm, per view "
                  + " / ".join(f"{v:.4f}" for v in result.per_view_mean_mm) + f", converged {result.converged}",
                  flush=True)
            rows.append({"frame": f, "component": comp, **dict(zip(POSE_KEYS, result.pose))})
            if (f, other) in listed:
                rows.append({"frame": f, "component": other, **dict(zip(POSE_KEYS, listed[f, other]))})
        if rim:
            print("rim models per view: " + "; ".join(f"mu {m.mu:g}/mm, sigma {m.sigma:.2f} px" if m else "none"
                                                       for m in models))
        path = args.out / f"{comp}_{'rim' if rim else 'plain'}.csv"
        with open(path, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
