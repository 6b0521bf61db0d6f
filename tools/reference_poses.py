"""Developer tool: the matcher's poses on the real biplane data against reference poses
that the matcher did not make (``fluorogui.reference.region_fit``: the mesh's projected
region fitted to the segmented dark region of both images, no outline, edge detector or
silhouette code of the matcher).

For every row of the matcher's poses (default ``tests/data/biplane_reference_poses.csv``,
made by ``tools/find_reference_poses.py --refine``) the region fit starts from the
matcher's pose (and, with ``--perturb MM_DEG``, also from that pose moved by a random
offset of that size per axis, to show the fit does not simply stay where it starts).
The other component's region at the matcher's pose, dilated by 3 px, is left out of the
evidence (``region_fit.component_masks``; only so that its pixels are not taken for this
component's). A fit whose overlap is too low to mean anything (``region_fit.LowOverlap``)
is refused: printed as such and counted apart, never averaged in. Prints per frame
and component the matcher minus the reference (dx dy dz mm, dalpha dbeta dgamma deg), the
region overlap (IoU) per view at the reference and at the matcher's pose (the same
evidence), and the mean, SD and max of |difference|;
``--out`` writes the rows as CSV.

``--project P.fluoro`` takes the poses of a tracked project instead (e.g. the one
``benchmarks/bench_tracking.py real`` prints: every frame of the 33 pairs, flagged ones
too, where the CSV stops at frame 160 because the tool that made it kept only poses whose
outline residual was small), with their status; ``--flagged`` fits only the poses that are
not ``matched`` and says of each whether it is a right pose (within ``--right MM_DEG``,
default 0.5, of the reference: largest translation difference and rotation angle), so each
check's flags can be judged. Pixels beyond the intensifier's field are left out of the
evidence (``region_fit.field_of_view``), as the matcher leaves them out.

``--xray`` measures the reference fitter's own error instead, on images of the
independent X-ray model (``fluorogui.reference.xray``: path length, Beer-Lambert, blur,
noise, a leg and bone background) with known poses: the real meshes at ``--flexion``
angles, two views 70 deg apart and tilted 10 deg, 1024 px of 0.3076 mm like the real
data, ``--starts`` starts per case moved uniformly by up to ``--perturb`` (default 2)
mm / deg per axis. Prints fit - truth per start and the mean, SD and max per component.

Usage: .venv/bin/python tools/reference_poses.py [--data DIR] [--poses CSV] [--frames N]
           [--components femoral tibial] [--perturb MM_DEG] [--out CSV]
           [--project P.fluoro [--flagged] [--right MM_DEG]] [--only FRAME ...]
       .venv/bin/python tools/reference_poses.py --xray [--flexion 30 45 60 90] [--starts 3]
       .venv/bin/python tools/reference_poses.py --single-plane [--data ../shared/data/single-plane-tka]

``--single-plane``: the three single-plane frames (one view: translation along the beam is
the weak direction of every method, the region fit's too), fitted from JointTrack's own
poses (``fem.jts``, ``tib.jts``); prints the region fit minus JointTrack and the matcher
(``Session.match`` from JointTrack's pose) minus the region fit, in the camera frame (z
along the beam).
"""
from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fluorogui.io.calibration import load_view  # noqa: E402
from fluorogui.io.images import read_image  # noqa: E402
from fluorogui.io.meshes.read import load_mesh  # noqa: E402
from fluorogui.reference.region_fit import (  # noqa: E402
    MIN_IOU,
    EdgeMesh,
    LowOverlap,
    component_masks,
    field_of_view,
    fit_pose,
    overlap_at,
    pose_difference,
    rotation,
    rotation_angle,
)

POSE_KEYS = ("x", "y", "z", "alpha", "beta", "gamma")
DIFF_LABELS = ("dx", "dy", "dz", "dalpha", "dbeta", "dgamma", "dangle")


def read_poses(path: Path) -> dict:
    """{(frame, component): pose} from a pose CSV with frame, component, x ... gamma."""
    with open(path, newline="") as fh:
        return {(int(r["frame"]), r["component"]): np.array([float(r[k]) for k in POSE_KEYS])
                for r in csv.DictReader(fh)}


def project_poses(path: Path) -> tuple[dict, dict]:
    """{(frame, component): pose} and {(frame, component): (status, failed checks)} of a
    saved project's pose records."""
    from fluorogui.workflow.session import Session

    session = Session.open(path)
    poses, status = {}, {}
    for (frame, comp), record in session.project.poses.items():
        poses[int(frame), comp] = np.asarray(record.pose, dtype=float)
        status[int(frame), comp] = str(record.status)
    return poses, status


def main(argv=None) -> int:
    default_data = ROOT.parent / "shared" / "data" / "biplane-tka"
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=default_data)
    ap.add_argument("--poses", type=Path, default=ROOT / "tests" / "data" / "biplane_reference_poses.csv")
    ap.add_argument("--frames", type=int, default=0, help="only the first N frames (0: all)")
    ap.add_argument("--components", nargs="+", default=["femoral", "tibial"])
    ap.add_argument("--perturb", type=float, default=0.0, help="also fit from a start moved by this (mm, deg)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--project", type=Path, help="the poses (and statuses) of a tracked project instead of --poses")
    ap.add_argument("--flagged", action="store_true", help="with --project: only the poses not matched")
    ap.add_argument("--only", type=int, nargs="+", help="only these frames")
    ap.add_argument("--right", type=float, default=0.5, help="a right pose: within this (mm, deg) of the reference")
    ap.add_argument("--xray", action="store_true", help="the fitter's own error on X-ray model images")
    ap.add_argument("--flexion", type=float, nargs="+", default=[30.0, 45.0, 60.0, 90.0])
    ap.add_argument("--starts", type=int, default=3)
    ap.add_argument("--single-plane", action="store_true", help="the single-plane data against JointTrack")
    args = ap.parse_args(argv)
    if args.xray:
        return xray_accuracy(args)
    if args.single_plane:
        return single_plane(args)

    data = args.data
    views = [load_view(data / f"calibration/cam{k}_mayacam2.txt") for k in (1, 2)]
    with open(data / "pairs.csv", newline="") as fh:
        pairs = {int(r["frame"]): (r["cam1"], r["cam2"]) for r in csv.DictReader(fh)}
    meshes = {c: EdgeMesh.from_arrays(*load_mesh(data / f"models/{c}_component.stl")) for c in ("femoral", "tibial")}
    status: dict = {}
    if args.project:
        matcher, status = project_poses(args.project)
        if args.flagged:
            matcher = {key: pose for key, pose in matcher.items() if status[key] != "matched"}
            others = project_poses(args.project)[0]  # the other component's region, whatever its status
        else:
            others = matcher
    else:
        matcher = others = read_poses(args.poses)
    frames = sorted({f for f, _ in matcher})
    if args.frames:
        frames = frames[:args.frames]
    if args.only:
        frames = [f for f in frames if f in args.only]
    rng = np.random.default_rng(args.seed)
    rows, refusals, t_all, refused_wrong = [], [], time.perf_counter(), 0
    print(f"{'frame':>5} {'component':9} " + " ".join(f"{k:>7}" for k in DIFF_LABELS)
          + "   iou1   iou2 (matcher's) secs" + ("  start-spread" if args.perturb else ""))
    for frame in frames:
        images = [read_image(data / p) for p in pairs[frame]]
        fields = [field_of_view(im) for im in images]
        for comp in args.components:
            if (frame, comp) not in matcher:
                continue
            pose = matcher[frame, comp]
            other = "tibial" if comp == "femoral" else "femoral"
            exclude = (component_masks(views, meshes[other], others[frame, other])
                       if (frame, other) in others else None)
            try:
                fit = fit_pose(views, images, meshes[comp], pose, exclude=exclude, fields=fields)
            except LowOverlap as refused:
                line = f"{frame:5d} {comp:9} refused: {refused}"
                if status:  # the pose itself against the evidence: too little overlap is no right pose
                    at = overlap_at(views, images, meshes[comp], pose, exclude=exclude, fields=fields)
                    wrong = min(at) < MIN_IOU
                    line += ("; overlap at this pose " + " ".join(f"{v:.2f}" for v in at)
                             + f"  {status[frame, comp]}" + (", NOT a right pose" if wrong else ", unknown"))
                    refused_wrong += wrong
                print(line, flush=True)
                refusals.append((frame, comp))
                continue
            diff = np.r_[pose_difference(pose, fit.pose), rotation_angle(pose, fit.pose)]
            row = {"frame": frame, "component": comp, **dict(zip(DIFF_LABELS, diff)),
                   "iou1": fit.iou[0], "iou2": fit.iou[1], "seconds": fit.seconds,
                   **dict(zip(("matcher_iou1", "matcher_iou2"), fit.iou_at(meshes[comp], pose))),
                   **{f"ref_{k}": v for k, v in zip(POSE_KEYS, fit.pose)}}
            line = (f"{frame:5d} {comp:9} " + " ".join(f"{d:7.3f}" for d in diff)
                    + f" {fit.iou[0]:6.4f} {fit.iou[1]:6.4f} {row['matcher_iou1']:6.4f} {row['matcher_iou2']:6.4f}"
                    + f" {fit.seconds:5.1f}")
            if args.perturb:
                start = pose + rng.choice([-1.0, 1.0], 6) * args.perturb
                try:
                    again = fit_pose(views, images, meshes[comp], start, exclude=exclude, fields=fields)
                except LowOverlap as refused:
                    again = refused.fit  # a restart that lost the component shows as a large spread
                spread = np.r_[pose_difference(again.pose, fit.pose), rotation_angle(again.pose, fit.pose)]
                row.update({f"restart_{k}": v for k, v in zip(DIFF_LABELS, spread)})
                line += (f"  {np.abs(spread[:3]).max():.3f} mm {spread[6]:.3f} deg")
            if status:
                row["status"] = status[frame, comp]
                row["right"] = bool(np.abs(diff[:3]).max() <= args.right and diff[6] <= args.right)
                line += f"  {row['status']}" + (", a right pose" if row["right"] else ", NOT a right pose")
            print(line, flush=True)
            rows.append(row)
    if refusals:
        print(f"\nrefused (overlap under {MIN_IOU:g} in a view), left out: "
              + ", ".join(f"{f} {c}" for f, c in refusals))
    flagged = [r for r in rows if r.get("status", "matched") != "matched"]
    if status and (flagged or refusals):
        print(f"not matched: {len(flagged)} fitted, {sum(r['right'] for r in flagged)} of them right poses "
              f"(within {args.right:g} mm / {args.right:g} deg of the reference); refused: "
              f"{sum(status[key] != 'matched' for key in refusals)} ({refused_wrong} of them not right poses: "
              f"their region overlaps the dark region under {MIN_IOU:g} in a view)")
    if not rows:
        print("no frames")
        return 1
    print()
    for comp in args.components:
        sel = [r for r in rows if r["component"] == comp]
        if not sel:
            continue
        d = np.array([[r[k] for k in DIFF_LABELS] for r in sel])
        ious = np.array([[r["iou1"], r["iou2"]] for r in sel])
        print(f"{comp} ({len(sel)} frames), matcher - reference:")
        print("        " + " ".join(f"{k:>7}" for k in DIFF_LABELS))
        print("mean    " + " ".join(f"{x:7.3f}" for x in d.mean(0)))
        print("SD      " + " ".join(f"{x:7.3f}" for x in d.std(0, ddof=1 if len(d) > 1 else 0)))
        print("max|d|  " + " ".join(f"{x:7.3f}" for x in np.abs(d).max(0)))
        print(f"IoU at the reference: median {np.median(ious):.4f}, min {ious.min():.4f}")
        at_matcher = np.array([[r["matcher_iou1"], r["matcher_iou2"]] for r in sel])
        print(f"IoU at the matcher's pose (same evidence): median {np.median(at_matcher):.4f}, "
              f"min {at_matcher.min():.4f}; reference - matcher: median {np.median(ious - at_matcher):.4f}")
        if args.perturb:
            s = np.array([[r[f"restart_{k}"] for k in DIFF_LABELS] for r in sel])
            print(f"restarts from +-{args.perturb:g} mm/deg: max |reference difference| "
                  f"{np.abs(s[:, :3]).max():.3f} mm, {s[:, 6].max():.3f} deg (rotation angle); "
                  f"median {np.median(np.abs(s[:, :3])):.3f} mm, {np.median(s[:, 6]):.3f} deg")
    print(f"\n{len(rows)} fits in {time.perf_counter() - t_all:.0f} s")
    if args.out:
        with open(args.out, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    return 0


def summary(label: str, errors: np.ndarray) -> None:
    print(f"{label} ({len(errors)} fits), fit - truth:")
    print("        " + " ".join(f"{k:>7}" for k in DIFF_LABELS))
    print("mean    " + " ".join(f"{x:7.3f}" for x in errors.mean(0)))
    print("SD      " + " ".join(f"{x:7.3f}" for x in errors.std(0, ddof=1 if len(errors) > 1 else 0)))
    print("max|d|  " + " ".join(f"{x:7.3f}" for x in np.abs(errors).max(0)))


def single_plane(args) -> int:
    """Region fits on the single-plane data against JointTrack's poses and the matcher's."""
    from fluorogui.io.calibration import jointtrack_to_pose, load_jointtrack_poses
    from fluorogui.io.importer import import_folder
    from fluorogui.workflow.session import Session

    data = args.data if args.data.name == "single-plane-tka" else args.data.parent / "single-plane-tka"
    session = Session(import_folder(data))
    views = list(session.views)
    files = {"femoral": "fem.jts", "tibial": "tib.jts"}
    print("single plane: z is along the beam, the weak direction")
    print(f"{'frame':>5} {'component':9} {'':22}" + " ".join(f"{k:>7}" for k in DIFF_LABELS) + "   iou")
    for comp in session.components():
        entry = next(m for m in session.project.models if m.component == comp)
        mesh = EdgeMesh.from_arrays(*load_mesh(entry.mesh_path))
        rows = load_jointtrack_poses(data / files[comp])
        for index, frame in enumerate(session.frames):
            images = session.images(frame)
            jointtrack = jointtrack_to_pose(rows[index])
            try:
                fit = fit_pose(views, images, mesh, jointtrack, fields=[field_of_view(im) for im in images])
            except LowOverlap as refused:
                print(f"{frame:5d} {comp:9} refused: {refused}", flush=True)
                continue
            session.set_pose(comp, frame, jointtrack)
            session.match(frame, comp)
            matched = session.project.poses[(frame, comp)].pose
            for label, d in (("region fit - JointTrack", np.r_[pose_difference(fit.pose, jointtrack),
                                                               rotation_angle(fit.pose, jointtrack)]),
                             ("matcher - region fit", np.r_[pose_difference(matched, fit.pose),
                                                            rotation_angle(matched, fit.pose)])):
                print(f"{frame:5d} {comp:9} {label:22}" + " ".join(f"{x:7.2f}" for x in d)
                      + f"  {fit.iou[0]:.4f}", flush=True)
    return 0


def xray_accuracy(args) -> int:
    """The fitter against known poses on independent X-ray model images."""
    from fluorogui.reference.xray import Body, XrayModel, xray_image
    from fluorogui.simulation.protocols import flexion_pose, two_views

    views = two_views(70.0, 10.0, image_size=(1024, 1024), pitch=315.0 / 1024.0)
    perturb = args.perturb or 2.0
    rng = np.random.default_rng(args.seed)
    t_all = time.perf_counter()
    print(f"{'component':9} {'flex':>4} " + " ".join(f"{k:>7}" for k in DIFF_LABELS) + "   iou1   iou2  secs")
    for comp in args.components:
        vertices, faces = load_mesh(args.data / f"models/{comp}_component.stl")
        mesh = EdgeMesh.from_arrays(vertices, faces)
        errors = []
        for flexion in args.flexion:
            truth = flexion_pose(vertices, flexion)
            world = vertices @ rotation(*truth[3:]).T + truth[:3]
            images = [xray_image(v, [Body(world, faces)], XrayModel(), rng) for v in views]
            for _ in range(args.starts):
                start = truth + rng.uniform(-perturb, perturb, 6)
                try:
                    fit, refused = fit_pose(views, images, mesh, start), ""
                    errors.append(np.r_[pose_difference(fit.pose, truth), rotation_angle(fit.pose, truth)])
                except LowOverlap as low:  # counted apart: printed, not in the summary
                    fit, refused = low.fit, "  refused (overlap too low)"
                err = np.r_[pose_difference(fit.pose, truth), rotation_angle(fit.pose, truth)]
                print(f"{comp:9} {flexion:4.0f} " + " ".join(f"{d:7.3f}" for d in err)
                      + f" {fit.iou[0]:6.4f} {fit.iou[1]:6.4f} {fit.seconds:5.1f}" + refused, flush=True)
        print()
        if errors:
            summary(comp, np.array(errors))
        print()
    print(f"done in {time.perf_counter() - t_all:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
