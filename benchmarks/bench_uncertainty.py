"""Does the reported per-pose SD match the spread over noise realisations?

    python benchmarks/bench_uncertainty.py [--realisations 100] [--noise 0.1] [--corr 3]
    python benchmarks/bench_uncertainty.py --xray MESH [--flexion 30 60] [--rim] [--background none]
    python benchmarks/bench_uncertainty.py --xray-real femoral|tibial [--frames 0 40 80 120] [--plain]

For each scene (a bent ellipsoid, outlines made without the matcher's code by
``fluorogui.reference.hull_outlines``) the matcher is run on many noise realisations; the
table gives, per pose variable, the observed SD of the matched poses, the median reported
SD, their ratio, and the ratio the SD would have if every outline point were counted as
an independent sample (``cluster_px`` ~ 0).

``--xray MESH``: the whole path instead, on images of the independent X-ray model
(``fluorogui.reference.xray``, quantum noise drawn anew per realisation; orthogonal
views, the mesh at each ``--flexion``): Canny outline, with ``--rim`` the rim refinement
as ``validate idealized --rim`` makes it, then the match from a perturbed start. Beside
the spread it gives the mean error and the RMS error, which hold the bias the noise does
not explain (the reported SD covers only the spread).

``--xray-real COMPONENT``: the real data's own geometry (``../shared/data/biplane-tka``:
its calibrated views, its mesh, at the reference poses of ``--frames`` from
``tests/data``) on images of the independent X-ray model, where the truth is known: the
matcher's whole loop as tracking runs it (``segment_and_match``: Canny outline, rim
refinement, match) and the independent region-overlap fit
(``fluorogui.reference.region_fit``), both from the same perturbed start, each one's
error against the truth (centroid in world mm, turn about the model's axes in degrees)
beside the reported SD; region fits it refuses (too low an overlap in a view) are counted
apart. It says how far each of the two methods that disagree on the real frames is off
where the answer is known. The images have the real data's background and blur: the leg
(soft tissue) along the component's own z axis through it, for the tray the bone and
cement under its plate and around its keel with the slope the real images show next to
the metal (``fluorogui.reference.zone``), and the real edges' blur; ``--plain`` makes
them as before (the X-ray model's default: a leg and a bone shaft about the world's z
axis, some 80 mm from the components, and its sharper blur).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from fluorogui.core.matching.matcher import match
from fluorogui.core.matching.problem import MatchProblem, MatchSettings
from fluorogui.core.matching.uncertainty import pose_covariance, pose_sd
from fluorogui.core.outlines.spline import OutlineSpline
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import pose_difference, rotation_matrix
from fluorogui.reference.hull_outlines import bent_ellipsoid, noisy_hull_outline
from fluorogui.simulation.protocols import dual_orthogonal_views

TRUTH = np.array([3.0, -2.0, 5.0, 20.0, -15.0, 30.0])


def scene(name, views, start_sd, args, mesh, world):
    rng = np.random.default_rng(args.seed)
    errors, reported, naive = [], [], []
    t0 = time.perf_counter()
    for _ in range(args.realisations):
        splines = [OutlineSpline.fit(noisy_hull_outline(v, world, args.noise, args.corr, rng=rng)) for v in views]
        problem = MatchProblem(mesh, views, splines)
        result = match(problem, TRUTH + rng.normal(0, start_sd, 6), MatchSettings())
        errors.append(pose_difference(result.pose, TRUTH))
        reported.append(result.sd)
        naive.append(pose_sd(pose_covariance(problem, result.pose, cluster_px=1e-6)))
    observed = np.std(errors, axis=0, ddof=1)
    rep, nai = np.median(reported, axis=0), np.median(naive, axis=0)
    print(f"{name} ({args.realisations} realisations, starts SD {start_sd:g} mm/deg, {time.perf_counter() - t0:.0f} s)")
    print(f"  {'':<18}" + "".join(f"{d:>9}" for d in ("x", "y", "z", "alpha", "beta", "gamma")))
    for label, row in (("observed SD", observed), ("reported SD", rep), ("reported/observed", rep / observed),
                       ("independent/obs.", nai / observed)):
        print(f"  {label:<18}" + "".join(f"{v:>9.4f}" for v in row))
    print()


def xray_scene(flexion, args):
    from fluorogui.core.matching.loop import fit_splines, segment_outlines
    from fluorogui.core.projection.pose import transform_points
    from fluorogui.io.meshes.read import load_mesh
    from fluorogui.reference.xray import MU_METAL, Body, XrayModel, xray_image
    from fluorogui.simulation.protocols import flexion_pose, rim_refined_outlines

    mesh = prepare_mesh(*load_mesh(args.xray))
    truth = flexion_pose(mesh.vertices, flexion)
    world = transform_points(truth, mesh.vertices)
    views = dual_orthogonal_views()
    model = XrayModel(background=[]) if args.background == "none" else XrayModel()
    rng = np.random.default_rng(args.seed)
    errors, reported = [], []
    t0 = time.perf_counter()
    for _ in range(args.realisations):
        images = [xray_image(v, [Body(world, mesh.faces, MU_METAL)], model, rng) for v in views]
        outlines = segment_outlines(images, views, mesh, truth)
        start = truth + rng.normal(0, 0.5, 6)
        weights = None
        if args.rim:  # as validate idealized --rim
            outlines, _, weights = rim_refined_outlines(images, views, mesh, outlines, start=start)
        result = match(MatchProblem(mesh, views, fit_splines(outlines, weights)), start)
        errors.append(pose_difference(result.pose, truth))
        reported.append(result.sd)
    errors = np.asarray(errors)
    observed, rep = np.std(errors, axis=0, ddof=1), np.median(reported, axis=0)
    rms = np.sqrt(np.mean(errors ** 2, axis=0))
    print(f"X-ray model, {args.xray.split('/')[-1]} at {flexion:g} deg" + (", rim" if args.rim else "")
          + (", no background" if args.background == "none" else "")
          + f" ({args.realisations} realisations, {time.perf_counter() - t0:.0f} s)")
    print(f"  {'':<18}" + "".join(f"{d:>9}" for d in ("x", "y", "z", "alpha", "beta", "gamma")))
    for label, row in (("mean error", errors.mean(0)), ("observed SD", observed), ("RMS error", rms),
                       ("reported SD", rep), ("reported/observed", rep / observed), ("reported/RMS", rep / rms)):
        print(f"  {label:<18}" + "".join(f"{v:>9.4f}" for v in row))
    print()


def xray_real_scene(args) -> None:
    import csv
    import tempfile
    from pathlib import Path

    from fluorogui import Session
    from fluorogui.core.matching.loop import segment_and_match
    from fluorogui.core.projection.pose import body_difference, transform_points
    from fluorogui.io.importer import import_folder
    from fluorogui.io.meshes.read import load_mesh
    from fluorogui.io.project.document import save_project
    from fluorogui.reference.region_fit import EdgeMesh, LowOverlap, field_of_view, fit_pose
    from fluorogui.reference.xray import MU_METAL, Body, XrayModel, xray_image

    root = Path(__file__).resolve().parents[1]
    data = root.parent / "shared" / "data" / "biplane-tka"
    project = Path(tempfile.mkdtemp(prefix="bench-uncertainty-")) / "real.fluoro"
    save_project(import_folder(data), project)
    views = Session.open(project).views
    names = ("x", "y", "z", "alpha", "beta", "gamma")
    truths = {int(r["frame"]): np.array([float(r[k]) for k in names])
              for r in csv.DictReader(open(root / "tests" / "data" / "biplane_reference_poses.csv"))
              if r["component"] == args.xray_real}
    missing = [f for f in args.frames if f not in truths]
    if missing:
        raise SystemExit(f"--frames: no {args.xray_real} reference pose for frame(s) "
                         + ", ".join(map(str, missing)) + f"; there are {sorted(truths)}")
    vertices, faces = load_mesh(data / "models" / f"{args.xray_real}_component.stl")
    mesh, edges = prepare_mesh(vertices, faces), EdgeMesh.from_arrays(vertices, faces)
    rng = np.random.default_rng(args.seed)
    ours, region, region_lost, reported = [], [], [], []
    print(f"X-ray model images ({'plain' if args.plain else 'real background and blur'}) of the real "
          f"{args.xray_real} component in the real views at the reference poses; "
          "error against the truth (centroid world x y z mm, turn about the model's x y z deg)")
    for frame in args.frames:
        truth = truths[frame]
        world = transform_points(truth, mesh.vertices)
        model = XrayModel() if args.plain else real_like_model(args.xray_real, vertices, faces, truth)
        images = [xray_image(v, [Body(world, mesh.faces, MU_METAL)], model, rng) for v in views]
        start = truth + rng.normal(0, 0.5, 6)
        result = segment_and_match(images, views, mesh, start)
        try:
            fit, lost = fit_pose(views, images, edges, start, fields=[field_of_view(im) for im in images]), False
        except LowOverlap as refused:  # too little of the component in a view's window: counted apart
            fit, lost = refused.fit, True
        ours.append(body_difference(result.pose, truth, mesh.centroid))
        region_error = body_difference(fit.pose, truth, mesh.centroid)
        (region_lost if lost else region).append(region_error)
        reported.append(result.sd_body)
        print(f"  frame {frame:3d}  matcher " + " ".join(f"{v:+.3f}" for v in ours[-1])
              + "  region fit " + " ".join(f"{v:+.3f}" for v in region_error)
              + " (overlap " + " ".join(f"{v:.3f}" for v in fit.iou) + (", refused" if lost else "") + ")"
              + "  reported SD " + " ".join(f"{v:.3f}" for v in result.sd_body))
    rows = [("matcher", ours), ("region fit", region), ("refused", region_lost)]
    for label, e in ((label, np.array(e)) for label, e in rows if e):
        print(f"  {label:<11} ({len(e)}) mean " + " ".join(f"{v:+.3f}" for v in e.mean(0))
              + "  RMS " + " ".join(f"{v:.3f}" for v in np.sqrt(np.mean(e ** 2, axis=0))))
    print("  median reported SD " + " ".join(f"{v:.3f}" for v in np.median(reported, axis=0)))


def real_like_model(component: str, vertices, faces, pose):
    """The X-ray model with the real images' background and blur for a component at ``pose``:
    soft tissue along the component's z axis (proximodistal) through its centroid, for the
    tray the bone and cement under its plate and around its keel."""
    from fluorogui.core.projection.pose import pose_to_matrix
    from fluorogui.reference.xray import MU_TISSUE, Cylinder, XrayModel
    from fluorogui.reference.zone import REAL_BLUR_PX, tray_zone

    M = pose_to_matrix(pose)
    centre = M[:3, :3] @ np.asarray(vertices, dtype=float).mean(0) + M[:3, 3]
    leg = Cylinder(tuple(centre), tuple(M[:3, 2]), 50.0, MU_TISSUE)
    zones = [tray_zone(vertices, faces, M)] if component == "tibial" else []
    return XrayModel(background=[leg], zones=zones, detector_blur_px=REAL_BLUR_PX)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--realisations", type=int, default=100)
    p.add_argument("--noise", type=float, default=0.1, help="outline noise SD (px)")
    p.add_argument("--corr", type=float, default=3.0, help="noise correlation along the outline (px, Gaussian sigma)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--xray", metavar="MESH", help="the whole path on X-ray model images of this mesh")
    p.add_argument("--flexion", type=float, nargs="+", default=[30.0, 60.0], help="with --xray")
    p.add_argument("--rim", action="store_true", help="with --xray: the rim refinement")
    p.add_argument("--background", choices=["knee", "none"], default="knee", help="with --xray")
    p.add_argument("--xray-real", choices=["femoral", "tibial"],
                   help="the real data's views, mesh and reference poses on X-ray model images")
    p.add_argument("--frames", type=int, nargs="+", default=[0, 40, 80, 120], help="with --xray-real")
    p.add_argument("--plain", action="store_true",
                   help="with --xray-real: the X-ray model's default background and blur, as before")
    args = p.parse_args()
    if args.xray_real:
        xray_real_scene(args)
        return
    if args.xray:
        for flexion in args.flexion:
            xray_scene(flexion, args)
        return
    v, f = bent_ellipsoid()
    mesh = prepare_mesh(v, f)
    world = v @ rotation_matrix(*TRUTH[3:]).T + TRUTH[:3]
    single = View.looking_at([-1000.0, 0, 0], [0, 0, 0], [0, 0, 1], 1200.0, image_size=(1024, 1024),
                             pitch=315 / 1024, name="single")
    scene("biplane, perturbed starts", dual_orthogonal_views(), 0.5, args, mesh, world)
    scene("single view (x out of plane), start at the truth", [single], 0.0, args, mesh, world)
    scene("single view, perturbed starts", [single], 0.5, args, mesh, world)


if __name__ == "__main__":
    main()
