"""Time budgets of engine operations: the speed claims the test suite used to assert.

Wall-clock asserts in unit tests failed on a loaded machine and proved nothing on an idle
one, so they live here and are run by hand. Each line prints the fastest of ``--repeat``
runs against its budget (the bound the test had, with what was measured then); the exit
status is 1 when any is over.

- spline closest point, 4000 queries on a 300-point circle (was tests/core/test_spline.py:
  < 20 ms; ~2-3 ms on a 2-core machine)
- first_self_intersection of a 2000-point figure eight (test_spline.py: < 0.2 s)
- render_silhouette of a ~73k-triangle sphere at 1024 px, the vectorised path
  (tests/core/test_render.py: < 3 s; 0.38-0.70 s with two other jobs on the 2 cores)
- build_demo_project with 4 frames (tests/io/test_demo.py: < 15 s; ~1.5 s)
- find_components on a rendered demo frame, from nothing including both shape libraries
  (tests/core/test_find.py: < 30 s; ~3-5 s), and near a prediction 5 mm / 15 deg off
  (< 10 s; ~1-1.5 s); benchmarks/bench_find.py times the real frames
- find_components cancelled on its fifth poll: the polls' largest gap (< 1 s) and the
  time from the cancelling poll to the raised Cancelled (< 0.2 s)

Usage: .venv/bin/python benchmarks/bench_budgets.py [--repeat 3] [--skip-find]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fluorogui.core.cancel import Cancelled  # noqa: E402
from fluorogui.core.outlines.spline import OutlineSpline, first_self_intersection  # noqa: E402
from fluorogui.core.projection.geometry import View  # noqa: E402
from fluorogui.core.projection.mesh import prepare_mesh  # noqa: E402
from fluorogui.core.projection.pose import (  # noqa: E402
    angles_from_matrix,
    rotation_matrix,
    rotvec_matrix,
    transform_points,
)
from fluorogui.core.search.find import find_components  # noqa: E402
from fluorogui.simulation.demo import (  # noqa: E402
    anatomy_meshes,
    build_demo_project,
    demo_views,
    knee_bend_poses,
    posed_anatomy,
    render_view,
)
from fluorogui.simulation.phantoms import femoral_component_mesh, tibial_component_mesh  # noqa: E402
from fluorogui.simulation.render import render_silhouette  # noqa: E402


def fastest(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(max(1, repeat)):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def spline_closest(repeat: int) -> float:
    th = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    spline = OutlineSpline.fit(np.array([300.0, 240.0]) + 80.0 * np.column_stack([np.cos(th), np.sin(th)]))
    rng = np.random.default_rng(2)
    a, r = rng.uniform(0, 2 * np.pi, 4000), 80.0 + rng.uniform(-10, 10, 4000)
    queries = np.array([300.0, 240.0]) + r[:, None] * np.column_stack([np.cos(a), np.sin(a)])
    spline.closest(queries)  # warm-up
    return fastest(lambda: spline.closest(queries), repeat)


def self_intersection(repeat: int) -> float:
    th = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    figure_eight = np.column_stack([200 * np.sin(th), 100 * np.sin(2 * th)])
    return fastest(lambda: first_self_intersection(figure_eight), repeat)


def uv_sphere(radius: float, n_lat: int, n_lon: int):
    lat = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    lon = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    pts = radius * np.column_stack([(np.sin(la) * np.cos(lo)).ravel(), (np.sin(la) * np.sin(lo)).ravel(),
                                    np.cos(la).ravel()])
    top, bottom = len(pts), len(pts) + 1
    vertices = np.vstack([pts, [[0, 0, radius], [0, 0, -radius]]])
    idx = np.arange(len(pts)).reshape(n_lat - 1, n_lon)
    nxt = np.roll(idx, -1, axis=1)
    faces = [np.column_stack([idx[:-1].ravel(), idx[1:].ravel(), nxt[1:].ravel()]),
             np.column_stack([idx[:-1].ravel(), nxt[1:].ravel(), nxt[:-1].ravel()]),
             np.column_stack([np.full(n_lon, top), idx[0], nxt[0]]),
             np.column_stack([np.full(n_lon, bottom), nxt[-1], idx[-1]])]
    return vertices, np.vstack(faces)


def render_large_mesh(repeat: int) -> float:
    view = View.looking_at([0, 0, -1000], [0, 0, 0], [0, -1, 0], 1000.0, image_size=(1024, 1024), pitch=0.25)
    vertices, faces = uv_sphere(30.0, 121, 304)  # ~73k triangles
    render_silhouette(view, vertices[:10], faces[:0])  # warm-up of numpy paths
    return fastest(lambda: render_silhouette(view, vertices + [0, 0, 50.0], faces), repeat)


def demo_build(repeat: int) -> float:
    def build():
        with tempfile.TemporaryDirectory() as folder:
            build_demo_project(Path(folder), frames=4)
    return fastest(build, repeat)


def find_scene():
    raw = {"femoral": femoral_component_mesh(), "tibial": tibial_component_mesh()}
    views = demo_views(1024)
    truth = knee_bend_poses(30.0, 0.6)
    anatomy = posed_anatomy(truth, anatomy_meshes())
    posed = [(transform_points(truth[name], v), f) for name, (v, f) in raw.items()]
    rng = np.random.default_rng(3)
    return [render_view(view, [posed], anatomy, rng) for view in views], views, raw, truth


def find_times(repeat: int) -> dict[str, float]:
    images, views, raw, truth = find_scene()
    # fresh meshes each run: the shape libraries are cached on the prepared mesh
    nothing = fastest(lambda: find_components(images, views, {n: prepare_mesh(*m) for n, m in raw.items()}), repeat)
    meshes = {name: prepare_mesh(*mesh) for name, mesh in raw.items()}
    find_components(images, views, meshes)  # the libraries, built once
    rng = np.random.default_rng(7)
    near = {}
    for name, pose in truth.items():
        axis, shift = rng.normal(size=3), rng.normal(size=3)
        R = rotvec_matrix(np.radians(15.0) * axis / np.linalg.norm(axis)) @ rotation_matrix(*pose[3:])
        c = rotation_matrix(*pose[3:]) @ meshes[name].centroid + pose[:3] + 5.0 * shift / np.linalg.norm(shift)
        near[name] = np.r_[c - R @ meshes[name].centroid, angles_from_matrix(R)]
    close = fastest(lambda: find_components(images, views, meshes, near=near), repeat)
    gaps, stops = [], []
    for _ in range(max(1, repeat)):
        polls = []

        def cancel_on_fifth(polls=polls):
            polls.append(time.perf_counter())
            return len(polls) >= 5

        try:
            find_components(images, views, meshes, cancel=cancel_on_fifth)
        except Cancelled:
            stops.append(time.perf_counter() - polls[-1])
        gaps.append(np.diff(polls).max())
    return {"nothing": nothing, "near": close, "poll_gap": min(gaps), "stop": min(stops) if stops else np.inf}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs of each; the fastest is reported")
    ap.add_argument("--skip-find", action="store_true", help="leave out find_components (the slowest part)")
    args = ap.parse_args(argv)
    rows = [("spline closest, 4000 queries", spline_closest(args.repeat), 0.02),
            ("self-intersection, 2000 points", self_intersection(args.repeat), 0.2),
            ("render 73k triangles, 1024 px", render_large_mesh(args.repeat), 3.0),
            ("demo project, 4 frames", demo_build(args.repeat), 15.0)]
    if not args.skip_find:
        t = find_times(args.repeat)
        rows += [("find from nothing, with the libraries", t["nothing"], 30.0),
                 ("find near a prediction", t["near"], 10.0),
                 ("find: largest gap between cancel polls", t["poll_gap"], 1.0),
                 ("find: cancelling poll to Cancelled", t["stop"], 0.2)]
    over = 0
    for name, seconds, budget in rows:
        flag = "" if seconds < budget else "  OVER BUDGET"
        over += bool(flag)
        print(f"{name:42s} {seconds:9.4f} s   budget {budget:g} s{flag}")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
