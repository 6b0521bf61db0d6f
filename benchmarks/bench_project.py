"""Project file size and save / open times of a 300-frame biplane session with two
components (1,200 outlines of 400 points with their splines, 600 matched poses).

    python benchmarks/bench_project.py [--frames 300] [--points 400]
"""
from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fluorogui.core.projection.geometry import View  # noqa: E402
from fluorogui.core.records import (  # noqa: E402
    ImageSequence,
    MatchRecord,
    ModelEntry,
    OutlineRecord,
    PoseRecord,
    Project,
    SplineRecord,
)
from fluorogui.io.project.document import load_project, save_project  # noqa: E402


def session(root: Path, frames: int, points: int) -> Project:
    rng = np.random.default_rng(0)
    numbers = list(range(frames))
    views = [View.looking_at((0, -1000, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(1024, 1024), pitch=0.4,
                             name="cam1"),
             View.looking_at((800, -600, 0), (0, 0, 0), (0, 0, 1), 1150, image_size=(1024, 1024), pitch=0.4,
                             name="cam2")]
    sequences = [ImageSequence([root / f"cam{k}" / f"{i:06d}.tif" for i in numbers]) for k in range(2)]
    models = [ModelEntry("femoral", root / "femoral.stl"), ModelEntry("tibial", root / "tibial.stl")]
    records, poses = {}, {}
    for frame in numbers:
        for component in ("femoral", "tibial"):
            for view in range(2):
                n = points // 4
                spline = SplineRecord(rng.random(n + 4), rng.random((2, n)) * 1000, 3, (0.0, 1.0))
                records[(frame, view, component)] = OutlineRecord(rng.random((points, 2)) * 1000, spline, False)
            match = MatchRecord(0.2, [0.1, 0.12], 300, 1.5, True, "fast", {"outline_points": 60},
                                {"edge_support": [0.9, 0.8]}, list(rng.random(60)))
            poses[(frame, component)] = PoseRecord(rng.normal(size=6), match, status="matched")
    return Project(views, sequences, numbers, models, records, poses, {"workflow": {}})


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--points", type=int, default=400)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.fluoro"
        project = session(Path(tmp), args.frames, args.points)
        started = time.perf_counter()
        save_project(project, path)
        saved = time.perf_counter() - started
        started = time.perf_counter()
        again = load_project(path)
        opened = time.perf_counter() - started
        assert again == project
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"{args.frames} frames x 2 views x 2 components, {args.points} points per outline: "
              f"{path.stat().st_size / 1e6:.1f} MB, save {saved:.2f} s, open {opened:.2f} s, "
              f"peak memory {peak:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
