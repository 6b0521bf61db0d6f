"""Bead calibration of generated cages through ``fluorogui calibrate geometry``: source error
and reprojection RMS per cage design and view.

    python benchmarks/bench_cages.py [--designs grid square shallow deep helix irregular dense]
                                     [--random N] [--noise SD] [--seed S]
    python benchmarks/bench_cages.py --sweep N [--seed S] [--designs ...]

Each design (``fluorogui.simulation.cages``) is imaged in the two views of ``TWO_VIEWS``
(and in ``--random`` more views: tilt 0-55 degrees from the plates' normal, any azimuth
and roll, 550-950 mm from the source), the images written as 16-bit TIFFs with the phantom
file, and the command run in-process exactly as from a shell. Per view it prints the
beads used, the reprojection RMS the command prints (px), and the fitted view's source
error and source-intensifier distance error against the camera that made the image (mm);
a view the command refuses is printed with its one-line error. The images come from a
ray-traced renderer of spheres (blur, vignetting, photon-like noise), not from the
calibration code.

``--sweep N`` checks the correspondence instead (``calibrate_view`` directly, the numbers
in ``core.calibration.correspondence``'s docstring): N random views per design (N/2 of the
dense grid; tilt 0-60 degrees, 500-1000 mm, noise SD 0.005-0.03), each pair right when its
blob lies within 1 px of its bead's true projection; it counts the views matched right,
matched with a wrong pair, and refused (the marker not told apart, or otherwise), and
prints every wrong match and every refusal that is not about the marker.

Designs: ``grid`` the lab's cage of issue 33 (28 beads of 2.5 mm on two plates 120 mm
apart, 4x4 and 4x3 grids of 30 mm, a 5 mm marker); ``square`` 4x4 on both plates (32);
``shallow`` and ``deep`` the grid with its plates 60 or 200 mm apart; ``helix`` 24 beads on
two turns of a helix of radius 50 mm over 120 mm; ``irregular`` 26 beads scattered in a
120 mm cube; ``dense`` two 6x6 plates of 20 mm pitch (72 beads).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import re
import tempfile
import time
from pathlib import Path

import numpy as np

from fluorogui.cli import main as fluorogui
from fluorogui.core.calibration.beads import BeadError, calibrate_view, detect_beads
from fluorogui.io.calibration import load_view
from fluorogui.simulation.cages import (
    helix_cage,
    irregular_cage,
    oblique_camera,
    render_cage,
    two_plate_grid_cage,
    two_view_cameras,
    write_cage_scene,
)

DESIGNS = {
    "grid": two_plate_grid_cage,
    "square": lambda: two_plate_grid_cage(grid_a=(4, 4), grid_b=(4, 4), marker_node=(1, 2)),
    "shallow": lambda: two_plate_grid_cage(plate_gap=60.0),
    "deep": lambda: two_plate_grid_cage(plate_gap=200.0),
    "helix": helix_cage,
    "irregular": irregular_cage,
    "dense": lambda: two_plate_grid_cage(spacing=20.0, grid_a=(6, 6), grid_b=(6, 6), marker_node=(1, 4)),
}


def random_cameras(count: int, rng) -> list:
    return [oblique_camera(rng.uniform(0, 55), azimuth_deg=rng.uniform(0, 360), roll_deg=rng.uniform(-180, 180),
                           source_to_cage=rng.uniform(550, 950), aim=rng.uniform(-15, 15, 3)) for _ in range(count)]


def calibrate_one(cage, camera, folder: Path, seed: int, noise: float) -> dict:
    """One view through the command: its printed line parsed, its written view compared."""
    images, phantom = write_cage_scene(cage, [camera], folder, seed=seed, noise=noise)
    out, err = io.StringIO(), io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = fluorogui(["calibrate", "geometry", "--image", str(images[0]), "--phantom", str(phantom),
                          "--pitch", str(camera.pitch), "--out-dir", str(folder / "out")])
    seconds = time.perf_counter() - start
    if code != 0:
        return {"refused": err.getvalue().strip().split(": ", 1)[-1], "seconds": seconds}
    line = out.getvalue().splitlines()[0]
    view = load_view(folder / "out" / "view1.json")
    return {"used": re.search(r"(\d+ of \d+) beads", line).group(1),
            "rms_px": float(re.search(r"reprojection RMS ([0-9.]+) px", line).group(1)),
            "source_mm": float(np.linalg.norm(view.source - camera.source)),
            "distance_mm": float(view.distance - camera.source_to_intensifier), "seconds": seconds}


def sweep(name: str, cage, views: int, seed: int) -> None:
    """The correspondence over ``views`` random views: right, wrong and refused."""
    rng = np.random.default_rng(seed)
    counts = {"right": 0, "wrong": 0, "refused (marker)": 0, "refused (other)": 0}
    seconds = []
    for k in range(views):
        camera = oblique_camera(rng.uniform(0, 60), azimuth_deg=rng.uniform(0, 360), roll_deg=rng.uniform(-180, 180),
                                source_to_cage=rng.uniform(500, 1000), aim=rng.uniform(-15, 15, 3))
        image = render_cage(cage, camera, seed=k, noise=rng.uniform(0.005, 0.03))
        start = time.perf_counter()
        try:
            result = calibrate_view(image, cage.beads, pitch=camera.pitch)
        except BeadError as exc:
            seconds.append(time.perf_counter() - start)
            marker = "told apart" in str(exc)
            counts["refused (marker)" if marker else "refused (other)"] += 1
            if not marker:
                print(f"{name:<10} view {k}: refused: {exc}")
            continue
        seconds.append(time.perf_counter() - start)
        centres, _ = detect_beads(image)
        truth, _ = camera.project(cage.beads)
        wrong = [(i, j) for i, j in result.pairs if np.linalg.norm(centres[j] - truth[i]) > 1.0]
        counts["wrong" if wrong else "right"] += 1
        if wrong:
            print(f"{name:<10} view {k}: {len(wrong)} wrong pairs of {result.used}")
    print(f"{name:<10} {len(cage.beads)} beads, {views} views: " + ", ".join(f"{v} {k}" for k, v in counts.items())
          + f"; {np.median(seconds):.2f} s median, {max(seconds):.2f} s max", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--designs", nargs="+", choices=sorted(DESIGNS), default=["grid", "helix", "irregular"])
    parser.add_argument("--random", type=int, default=0, metavar="N", help="N random views per design as well")
    parser.add_argument("--noise", type=float, default=0.012, help="noise SD on the bright field (default 0.012)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sweep", type=int, default=0, metavar="N", help="check the pairs in N random views instead")
    args = parser.parse_args()
    if args.sweep:
        for name in args.designs:
            sweep(name, DESIGNS[name](), args.sweep // 2 if name == "dense" else args.sweep, args.seed)
        return
    rng = np.random.default_rng(args.seed)
    print(f"{'design':<10} {'view':<22} {'beads':>9} {'RMS px':>8} {'source mm':>10} {'SID mm':>8} {'s':>5}")
    for name in args.designs:
        cage = DESIGNS[name]()
        cameras = [(f"TWO_VIEWS {k + 1}", c) for k, c in enumerate(two_view_cameras())]
        for k, camera in enumerate(random_cameras(args.random, rng)):
            cameras.append((f"random {k + 1}", camera))
        summary = []
        for k, (label, camera) in enumerate(cameras):
            with tempfile.TemporaryDirectory() as folder:
                r = calibrate_one(cage, camera, Path(folder), args.seed + k, args.noise)
            if "refused" in r:
                print(f"{name:<10} {label:<22} refused ({r['seconds']:.1f} s): {r['refused']}")
                continue
            summary.append(r)
            print(f"{name:<10} {label:<22} {r['used']:>9} {r['rms_px']:8.4f} {r['source_mm']:10.3f} "
                  f"{r['distance_mm']:+8.3f} {r['seconds']:5.1f}")
        if len(cameras) > 2 and summary:
            source = np.array([r["source_mm"] for r in summary])
            rms = np.array([r["rms_px"] for r in summary])
            print(f"{name:<10} {'summary':<22} {len(summary)} of {len(cameras)} views calibrated; source error "
                  f"median {np.median(source):.3f} max {source.max():.3f} mm, RMS median {np.median(rms):.4f} "
                  f"max {rms.max():.4f} px")


if __name__ == "__main__":
    main()
