"""Developer tool: reference poses of both components on the real biplane data.

Frame 1: global search (*find implants*: ``core.search.find.find_components``), then two
passes of Canny outlines along the found pose and the fast matcher. Following frames: start
from the previous frame's pose, Canny outlines along it, fast matcher, twice. A component
whose match fails or whose objective exceeds ``--max-objective`` is lost; with ``--reinit``
(default) the global search runs again for it in the next frames until it is found. A pose
is written only when its mean outline residual is at most ``--max-view-px`` in both views (frames where it is not are
reported and skipped). Writes ``tests/data/biplane_reference_poses.csv`` and overlay PNGs
(projected silhouettes on both images) to ``--overlays``.

``--components tibial`` recomputes only the tibia: the rows of the other components in
an existing ``--out`` file are kept unchanged (first, in their order), the tibial rows
are replaced.

``--refine`` instead re-matches every row of an existing ``--out`` file from its own pose
with the current segment -> match loop (``core.pipeline.segment_and_match``, the one the
app, the command line and tracking use) and rewrites the file: after a change to the
segmentation or the matcher, the reference poses are where a careful single-frame match
from the old reference lands today, independent of tracking, prediction and find.

Usage: .venv/bin/python tools/find_reference_poses.py [--data DIR] [--frames N] [--overlays DIR]
           [--components femoral tibial] [--no-reinit] [--max-view-px PX] [--refine]
"""
from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pyvista as pv

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fluorogui.core.matching.loop import match_images  # noqa: E402
from fluorogui.core.projection.geometry import View  # noqa: E402
from fluorogui.core.projection.mesh import prepare_mesh  # noqa: E402
from fluorogui.core.projection.pose import rotation_matrix  # noqa: E402
from fluorogui.core.projection.silhouette import mesh_silhouette  # noqa: E402
from fluorogui.core.search.find import find_components  # noqa: E402

COMPONENTS = ("femoral", "tibial")
COLOURS = {"femoral": (0, 0, 255), "tibial": (0, 200, 0)}


def load_views(data: Path) -> list[View]:
    try:
        from fluorogui.io.calibration import load_view
        return [load_view(data / f"calibration/cam{k}_mayacam2.txt") for k in (1, 2)]
    except ImportError:  # parse MayaCam 2.0 locally
        views = []
        for k in (1, 2):
            lines = [ln.strip() for ln in (data / f"calibration/cam{k}_mayacam2.txt").read_text().splitlines()]
            nums = [list(map(float, ln.split(","))) for ln in lines if ln and ln[0] in "-0123456789"]
            size, K, R, t = nums[0], np.array(nums[1:4]), np.array(nums[4:7]), np.array([n[0] for n in nums[7:10]])
            views.append(View.from_pinhole(K, R, t, (int(size[0]), int(size[1])), name=f"cam{k}"))
        return views


def load_mesh(path: Path):
    m = pv.read(str(path)).clean()
    return prepare_mesh(np.asarray(m.points, dtype=float), m.faces.reshape(-1, 4)[:, 1:])


def silhouette_px(mesh, pose, view):
    return mesh_silhouette(mesh, rotation_matrix(*pose[3:]), pose[:3], view).points_px


def outline_iou(mesh, pose, view, outline, shape) -> float:
    """IoU of the projected silhouette with the region inside the image outline."""
    a = np.zeros(shape, np.uint8)
    b = np.zeros(shape, np.uint8)
    cv2.fillPoly(a, [np.round(silhouette_px(mesh, pose, view) * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    cv2.fillPoly(b, [np.round(np.asarray(outline) * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 0.0


def overlay(images, views, meshes, poses, splines, path: Path, label: str) -> None:
    tiles = []
    for k, (img, view) in enumerate(zip(images, views)):
        vis = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        for name, pose in poses.items():
            pts = silhouette_px(meshes[name], pose, view)
            cv2.polylines(vis, [np.round(pts * 16).astype(np.int32)], True, COLOURS[name], 1, cv2.LINE_AA, 4)
            if name in splines:
                sp = splines[name][k].sample(max(64, int(splines[name][k].length_px)))
                cv2.polylines(vis, [np.round(sp * 16).astype(np.int32)], True, (255, 160, 0), 1, cv2.LINE_AA, 4)
        cv2.putText(vis, f"{label} cam{k + 1}", (20, 40), cv2.FONT_HERSHEY_SIMPLEX, 1.2, (0, 255, 255), 2)
        tiles.append(vis)
    cv2.imwrite(str(path), np.hstack(tiles))


def global_search(images, views, meshes, names) -> dict[str, np.ndarray]:
    """Poses of the ``names`` components from scratch (*find implants*: dark regions, an
    orientation scan on edge maps, refinement on Canny outlines), each matched again on
    Canny outlines for two passes from the placement and from every candidate the search
    kept; the best match is used, confident or not (the residual limit decides later)."""
    try:
        found = find_components(list(images), list(views), {n: meshes[n] for n in names})
    except ValueError as exc:
        print(f"  global search failed: {exc}", flush=True)
        return {}
    poses = {}
    for name, p in found.items():
        starts = ([p.pose] if p.pose is not None else []) + [pose for _score, pose in p.alternatives]
        best = None
        for start in starts:
            try:
                res, _ = match_images(images, views, meshes[name], start, passes=2)
            except ValueError:
                continue
            if best is None or res.objective_mm < best.objective_mm:
                best = res
        if best is None:
            print(f"  {name}: not placed ({p.reason})", flush=True)
            continue
        poses[name] = best.pose
        print(f"  {name} found{'' if p.found else ' (not confident: ' + p.reason + ')'}: objective "
              f"{best.objective_mm:.2f} mm, IoU {np.round(p.iou, 3)}, {p.seconds:.1f} s", flush=True)
    return poses


HEADER = ["frame", "component", "x", "y", "z", "alpha", "beta", "gamma", "objective_mm",
          "view1_mean_mm", "view2_mean_mm", "view1_iou", "view2_iou"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared/data/biplane-tka")
    ap.add_argument("--frames", type=int, default=0, help="number of frames (0: all)")
    ap.add_argument("--out", type=Path, default=ROOT / "tests/data/biplane_reference_poses.csv")
    ap.add_argument("--overlays", type=Path, default=Path("/tmp/reference_overlays"))
    ap.add_argument("--max-objective", type=float, default=3.0,
                    help="a component whose objective (mm) exceeds this is lost")
    ap.add_argument("--max-view-px", type=float, default=1.0,
                    help="write a pose only when the mean outline residual of both views is at most this (px)")
    ap.add_argument("--components", nargs="+", choices=COMPONENTS, default=list(COMPONENTS),
                    help="components to (re)compute; rows of the others in --out are kept")
    ap.add_argument("--no-reinit", dest="reinit", action="store_false",
                    help="stop tracking a lost component instead of searching for it again")
    ap.add_argument("--refine", action="store_true",
                    help="re-match every row of --out from its pose with the current loop and rewrite it")
    args = ap.parse_args(argv)
    if args.refine:
        return refine(args)
    names = [n for n in COMPONENTS if n in args.components]
    kept_rows = []
    if args.out.exists() and set(names) != set(COMPONENTS):
        with open(args.out, newline="") as fh:
            kept_rows = [r for r in csv.reader(fh)][1:]
        kept_rows = [r for r in kept_rows if r and r[1] not in names]

    views = load_views(args.data)
    meshes = {name: load_mesh(args.data / f"models/{name}_component.stl") for name in COMPONENTS}
    rows = list(csv.DictReader(open(args.data / "pairs.csv")))
    if args.frames:
        rows = rows[: args.frames]
    args.overlays.mkdir(parents=True, exist_ok=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)

    poses: dict[str, np.ndarray] = {}
    lost: set[str] = set()
    out_rows = []
    t_start = time.perf_counter()
    for n, row in enumerate(rows):
        t0 = time.perf_counter()
        images = [cv2.imread(str(args.data / row[k]), cv2.IMREAD_GRAYSCALE) for k in ("cam1", "cam2")]
        wanted = [name for name in names if name not in poses]
        if wanted and (n == 0 or args.reinit):
            print(f"frame {row['frame']}: global search for {', '.join(wanted)}", flush=True)
            poses.update(global_search(images, views, meshes, wanted))
        searched = set(wanted) if wanted and (n == 0 or args.reinit) else set()
        splines_by = {}
        for name in names:
            if name not in poses:
                continue
            try:
                res, splines = match_images(images, views, meshes[name], poses[name], passes=2)
            except ValueError as exc:
                res = None
                print(f"frame {row['frame']}: {name}: no outline ({exc})", flush=True)
            if args.reinit and name not in searched and (res is None or res.objective_mm > args.max_objective):
                # lost while tracking: search for it in this frame from scratch
                print(f"frame {row['frame']}: {name}: lost; global search", flush=True)
                searched.add(name)
                found = global_search(images, views, meshes, [name])
                if name in found:
                    try:
                        res, splines = match_images(images, views, meshes[name], found[name], passes=2)
                    except ValueError as exc:
                        res = None
                        print(f"frame {row['frame']}: {name}: no outline ({exc})", flush=True)
            if res is None:
                print(f"frame {row['frame']}: {name}: lost", flush=True)
                del poses[name]
                lost.add(name)
                continue
            ious = [outline_iou(meshes[name], res.pose, v, s.sample(max(64, int(s.length_px))), img.shape)
                    for v, s, img in zip(views, splines, images)]
            px = [m / v.mm_per_px() for m, v in zip(res.per_view_mean_mm, views)]
            print(f"frame {row['frame']}: {name}: objective {res.objective_mm:.3f} mm "
                  f"(views {res.per_view_mean_mm[0]:.3f}, {res.per_view_mean_mm[1]:.3f} mm = "
                  f"{px[0]:.2f}, {px[1]:.2f} px), IoU {ious[0]:.3f} / {ious[1]:.3f}, "
                  f"{'converged' if res.converged else res.message}", flush=True)
            if res.objective_mm > args.max_objective:
                print(f"frame {row['frame']}: {name}: objective too large; lost", flush=True)
                del poses[name]
                lost.add(name)
                continue
            poses[name] = res.pose
            splines_by[name] = splines
            if max(px) > args.max_view_px or not res.converged:
                print(f"frame {row['frame']}: {name}: residual above {args.max_view_px} px or not converged; "
                      "not written", flush=True)
                continue
            out_rows.append([row["frame"], name, *[f"{v:.4f}" for v in res.pose], f"{res.objective_mm:.4f}",
                             f"{res.per_view_mean_mm[0]:.4f}", f"{res.per_view_mean_mm[1]:.4f}",
                             f"{ious[0]:.4f}", f"{ious[1]:.4f}"])
        overlay(images, views, meshes, {k: v for k, v in poses.items() if k in splines_by}, splines_by,
                args.overlays / f"frame_{int(row['frame']):04d}.png", f"frame {row['frame']}")
        print(f"frame {row['frame']}: {time.perf_counter() - t0:.1f} s", flush=True)
        if not args.reinit and len(lost) == len(names):
            break
        # write as we go so a long run leaves a usable file
        with open(args.out, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(HEADER)
            w.writerows(kept_rows)
            w.writerows(out_rows)
    print(f"{len(out_rows)} poses in {time.perf_counter() - t_start:.0f} s -> {args.out}")
    return 0


def refine(args) -> int:
    """Re-match every reference row from its own pose; keep converged ones within --max-view-px."""
    from fluorogui.core.matching.loop import segment_and_match
    from fluorogui.core.projection.pose import pose_error

    views = load_views(args.data)
    meshes = {name: load_mesh(args.data / f"models/{name}_component.stl") for name in COMPONENTS}
    pairs = {r["frame"]: r for r in csv.DictReader(open(args.data / "pairs.csv"))}
    with open(args.out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    out_rows = []
    for row in rows:
        frame, name = row["frame"], row["component"]
        images = [cv2.imread(str(args.data / pairs[frame][k]), cv2.IMREAD_GRAYSCALE) for k in ("cam1", "cam2")]
        old = np.array([float(row[k]) for k in ("x", "y", "z", "alpha", "beta", "gamma")])
        out = segment_and_match(images, views, meshes[name], old)
        res = out
        px = [m / v.mm_per_px() for m, v in zip(res.per_view_mean_mm, views)]
        moved = pose_error(res.pose, old)
        note = f"moved {np.abs(moved[:3]).max():.3f} mm / {np.abs(moved[3:]).max():.3f} deg"
        if not res.converged or max(px) > args.max_view_px:
            print(f"frame {frame}: {name}: dropped ({'not converged' if not res.converged else 'residual'}; {note})")
            continue
        ious = [outline_iou(meshes[name], res.pose, v, s.sample(max(64, int(s.length_px))), img.shape)
                for v, s, img in zip(views, out.splines, images)]
        print(f"frame {frame}: {name}: {note}, views {px[0]:.2f} / {px[1]:.2f} px", flush=True)
        out_rows.append([frame, name, *[f"{v:.4f}" for v in res.pose], f"{res.objective_mm:.4f}",
                         f"{res.per_view_mean_mm[0]:.4f}", f"{res.per_view_mean_mm[1]:.4f}",
                         f"{ious[0]:.4f}", f"{ious[1]:.4f}"])
    with open(args.out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(HEADER)
        w.writerows(out_rows)
    print(f"{len(out_rows)} of {len(rows)} reference poses refined -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
