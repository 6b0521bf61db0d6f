"""``fluorogui validate idealized | spheres | repeatability``: the paper's validation
protocols (Tables 1-4) over ``fluorogui.simulation.protocols``, printed in the paper's table
layout and written to results.json / results.csv with ``--out``."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fluorogui.cli.common import (
    OUTLINE_POINTS_RANGE,
    POINTS_RANGE,
    SEED_RANGE,
    STARTS_RANGE,
    Numbers,
    UsageError,
    add_rim_options,
    finite_float,
    int_in,
)
from fluorogui.cli.inputs import load_images, load_model, load_views, match_settings, outline_splines, start_pose
from fluorogui.io.files import check_output_folder


def add_parser(sub):
    v = sub.add_parser("validate", help="the paper's validation protocols")
    vs = v.add_subparsers(dest="protocol", parser_class=type(v), required=True)
    vi = vs.add_parser("idealized", help="Tables 1/2: rendered images of a model at flexion poses")
    vi.add_argument("--model", action="append", required=True, metavar="MESH")
    vi.add_argument("--flexion", nargs="+", type=finite_float, default=[30.0, 45.0, 60.0, 90.0])
    vi.add_argument("--density", nargs="+", type=int_in(*POINTS_RANGE), default=[15000],
                    help="point-model sizes (paper method)")
    vi.add_argument("--renderer", choices=["xray", "silhouette"], default="xray",
                    help="xray: the independent image model (default); silhouette: the old filled silhouette")
    vi.add_argument("--variant", nargs="+", default=[""], metavar="V",
                    help="mesh variants: none, mirrored, scaled+15, scaled-15, ps-box (femoral), "
                         "symmetric, symmetric-ap (tray)")
    vi.add_argument("--angle", type=finite_float, default=90.0, help="degrees between the two views")
    vi.add_argument("--tilt", type=finite_float, default=0.0, help="degrees the views are tilted out of a common plane")
    vi.add_argument("--offset", nargs=2, type=finite_float, default=[0.0, 0.0], metavar=("DU", "DV"),
                    help="principal point offset (px): the object off the image centre")
    vi.add_argument("--source-distance", nargs=2, type=finite_float, default=[1000.0, 1000.0], metavar=("D1", "D2"),
                    help="source to object distance per view (mm)")
    vi.add_argument("--bits", type=int, choices=[8, 16], default=16, help="xray: image bit depth")
    vi.add_argument("--mu", type=finite_float, default=None,
                    help="xray: the metal's attenuation (1/mm; default CoCr, 1.0)")
    vi.add_argument("--photons", type=finite_float, default=3000.0, metavar="N",
                    help="xray: quanta per pixel without an object (quantum noise; 0: none, to see bias alone)")
    vi.add_argument("--background", choices=["knee", "none"], default="knee",
                    help="xray: knee: the leg's soft tissue and a bone shaft behind the component; "
                         "none: air, so that a bias from the bone's edges shows apart from the method's own")
    vi.add_argument("--image-size", type=int, default=1024, help="image width and height (px; same field of view)")
    vi.add_argument("--distortion", type=finite_float, default=0.0, metavar="K1",
                    help="xray: radial distortion applied to the images, then corrected before matching")
    vi.add_argument("--other", metavar="MESH", help="the knee's other component, placed across an 8 mm insert at "
                    "the case's flexion and imaged in the same images (masked as the knee workflow does)")
    vi.add_argument("--other-is", choices=["tibial", "femoral"], default=None,
                    help="which component --other is (default: from its file name)")
    vi.add_argument("--start-sd", type=finite_float, default=20.0 / 3.0, metavar="SD",
                    help="the starts' Gaussian SD (mm and deg) within +/-20 (default 20/3: the range is 3 SD)")
    vi.add_argument("--draws", type=int_in(1, 100), default=1, metavar="N",
                    help="images per case, each with its own noise (seeds SEED .. SEED+N-1; --starts per image): "
                         "one image's noise moves every start of a case alike")
    vi.add_argument("--single-view", action="store_true", help="match in the first view only (single-plane)")
    vi.add_argument("--basin", nargs=2, type=finite_float, default=[WRONG_MM, WRONG_DEG], metavar=("MM", "DEG"),
                    help="a start ending farther than this from the truth is in a wrong basin (default 0.05 0.05)")
    add_rim_options(vi, "validation")
    _add_validation_options(vi)
    vp = vs.add_parser("spheres", help="Table 3: eight stacked 12.70 mm spheres")
    _add_validation_options(vp)
    vr = vs.add_parser("repeatability", help="Table 4: perturbed starts of a given pose on real images")
    vr.add_argument("--camera", action="append", required=True, metavar="CAM")
    vr.add_argument("--image", action="append", metavar="IMG")
    vr.add_argument("--model", required=True, metavar="MESH")
    vr.add_argument("--pose", action=Numbers, type=finite_float, metavar=("X", "Y", "Z", "ALPHA", "BETA", "GAMMA"))
    vr.add_argument("--outline", action="append", metavar="CSV")
    vr.add_argument("--reference", metavar="CSV", help="poses per frame: frame,component,x,y,z,alpha,beta,gamma")
    vr.add_argument("--pairs", metavar="CSV", help="with --reference: frame,cam1,cam2 image pairs")
    vr.add_argument("--component", help="with --reference: the component of --model")
    vr.add_argument("--frames", type=int_in(0, 1_000_000), default=0, help="with --reference: first N frames (0 = all)")
    _add_validation_options(vr)
    return v


def run(args) -> int:
    protocols = {"idealized": cmd_validate_idealized, "spheres": cmd_validate_spheres,
                 "repeatability": cmd_validate_repeatability}
    return protocols[args.protocol](args)


def _add_validation_options(p):
    p.add_argument("--method", nargs="+", choices=["fast", "paper"], default=["fast"])
    p.add_argument("--starts", type=int_in(*STARTS_RANGE), default=10, help="perturbed starts per case")
    p.add_argument("--outline-points", type=int_in(*OUTLINE_POINTS_RANGE), default=None)
    p.add_argument("--seed", type=int_in(*SEED_RANGE), default=0)
    p.add_argument("--out", metavar="DIR", help="write results.json and results.csv here")
    p.add_argument("--json", action="store_true", help="print the results as JSON")


def _write_outputs(out_dir, payload: dict, rows: list[dict]):
    from fluorogui.io.files import atomic_write_text
    from fluorogui.io.pose_files import write_csv

    if not out_dir:
        return
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "results.json", json.dumps(payload, indent=2))
    if rows:  # quoted where needed ("45 deg, 15000 pts", a model name with a comma)
        keys = list(rows[0].keys())
        write_csv(out / "results.csv", [], keys, [[r[k] for k in keys] for r in rows])
    print(f"wrote {out / 'results.json'} and {out / 'results.csv'}")


def _fmt_dof(summary, k):
    return f"{summary.mean[k]:+.3f}±{summary.sd[k]:.3f} [{summary.rmse[k]:.3f}]"


def _print_table(title, rows):
    """rows: (label, Summary)."""
    from fluorogui.simulation.protocols import DOF_LABELS

    print(title)
    head = f"{'case':<22}" + "".join(f"{d + (' (mm)' if k < 3 else ' (deg)'):>24}" for k, d in enumerate(DOF_LABELS))
    print(head + f"{'conv':>7}{'s/match':>9}{'calls':>7}")
    for label, s in rows:
        print(f"{label:<22}" + "".join(f"{_fmt_dof(s, k):>24}" for k in range(6))
              + f"{s.n_converged:>4}/{s.n_runs:<2}{s.median_seconds:>9.3f}{s.median_calls:>7.0f}")
    print()


def _case_row(model, method, case):
    s = case.summary
    row = {"model": model, "method": method, "case": case.label, "n_runs": s.n_runs, "n_converged": s.n_converged,
           "median_seconds": round(s.median_seconds, 4), "median_calls": s.median_calls}
    from fluorogui.simulation.protocols import DOF_LABELS

    for k, d in enumerate(DOF_LABELS):
        values = (round(float(x), 5) for x in (s.mean[k], s.sd[k], s.rmse[k]))
        row[f"{d}_mean"], row[f"{d}_sd"], row[f"{d}_rmse"] = values
    return row


def _xray_renderer(args):
    """The independent image model as ``idealized_case``'s renderer (None: the old one)."""
    if args.renderer != "xray":
        return None
    from fluorogui.reference.xray import MU_METAL, Body, XrayModel, undistort_image, xray_image

    if args.photons < 0:
        raise UsageError(f"fluorogui: --photons {args.photons:g}: give 0 (no noise) or more")
    model = XrayModel(bits=args.bits, distortion_k1=args.distortion, photons=args.photons or None)
    if args.background == "none":
        model.background = []
    mu = args.mu or MU_METAL

    def render(view, meshes, rng):
        image = xray_image(view, [Body(v, f, mu) for v, f in meshes], model, rng)
        return undistort_image(image, args.distortion) if args.distortion else image

    return render


#: a start ending farther than this from the truth (mm, deg) is in a wrong basin
WRONG_MM, WRONG_DEG = 0.05, 0.05


def cmd_validate_idealized(args) -> int:
    from fluorogui.simulation.protocols import idealized_case, mesh_variant, two_views

    check_output_folder(args.out)
    _check_settings(args)
    if args.seed + args.draws - 1 > SEED_RANGE[1]:
        raise UsageError(f"fluorogui: --seed {args.seed} with --draws {args.draws}: "
                         f"the last seed exceeds {SEED_RANGE[1]}")
    if not 64 <= args.image_size <= 4096:
        raise UsageError(f"fluorogui: --image-size {args.image_size}: give 64 to 4096 pixels")
    views = two_views(args.angle, args.tilt, offset_px=tuple(args.offset), source_to_centre=tuple(args.source_distance),
                      image_size=(args.image_size, args.image_size), pitch=315.0 / args.image_size)
    beam = None
    if args.single_view:
        views, beam = views[:1], np.asarray(views[0].normal, dtype=float)
    other, other_is_tibial = _other_component(args)
    render = _xray_renderer(args)
    rim = {"on": ", rim refinement", "off": ", no rim refinement",
           "auto": ", rim refinement where the edge is soft"}[args.rim]
    image_model = ""
    if render:
        image_model = (f", {args.bits}-bit, metal {args.mu or 1.0:g}/mm, distortion k1 {args.distortion:g} "
                       "(corrected), " + (f"{args.photons:g} quanta/px" if args.photons else "no noise")
                       + ("" if args.background == "knee" else ", no background"))
    print(f"idealized: {args.renderer} images, " + ("one view (single-plane) of " if args.single_view else "")
          + f"views {args.angle:g} deg apart, tilt {args.tilt:g} deg, "
          f"offset {args.offset[0]:g}/{args.offset[1]:g} px, sources {args.source_distance[0]:g}/"
          f"{args.source_distance[1]:g} mm" + rim + image_model
          + (f"; with {Path(args.other).name} overlapping" if other else "")
          + (f"; {args.draws} noise draws per case (seeds {args.seed}-{args.seed + args.draws - 1}), each a row"
             if args.draws > 1 else "")
          + f"; {args.starts} starts per " + ("draw" if args.draws > 1 else "case")
          + f" (SD {args.start_sd:.3g} within ±20 mm / ±20 deg)"
          + f"; wrong basin beyond {args.basin[0]:g} mm / {args.basin[1]:g} deg"
          + (f" ({SINGLE_VIEW_DEPTH_MM:g} mm along the beam)" if beam is not None else "") + "\n")
    payload, rows = {"protocol": "idealized", "renderer": args.renderer, "cases": []}, []
    for model_path in args.model:
        base = load_model(model_path)
        for variant in [v if v != "none" else "" for v in args.variant]:
            try:
                vertices, faces = mesh_variant(base.vertices, base.faces, variant)
            except ValueError as exc:
                raise UsageError(f"fluorogui: --variant: {exc}") from None
            name = Path(model_path).name + (f" ({variant})" if variant else "")
            for method in args.method:
                table = []
                densities = args.density if method == "paper" else [None]
                for density in densities:
                    for flexion, draw in ((f, d) for f in args.flexion for d in range(args.draws)):
                        settings = match_settings(args, method, multistart=False)
                        if density:
                            settings.model_points = density
                        label = (f"{flexion:g} deg" + (f", {density} pts" if density else "")
                                 + (f", draw {draw + 1}" if args.draws > 1 else ""))
                        case = idealized_case(vertices, faces, flexion, settings, n_starts=args.starts,
                                              seed=args.seed + draw,
                                              views=views, label=label, render=render, other=other,
                                              other_is_tibial=other_is_tibial, start_sd_fraction=args.start_sd / 20.0,
                                              rim=args.rim)
                        if "occluded" in case.extra:
                            case.label = label = label + " (hid " + "/".join(
                                f"{100 * o:.0f}" for o in case.extra["occluded"]) + " %)"
                        if args.rim == "auto" and case.extra["rim_refined"]:  # the views found soft
                            case.label = label = label + " [rim " + "+".join(
                                str(k + 1) for k in case.extra["rim_refined"]) + "]"
                        table.append((label, case))
                        payload["cases"].append({"model": model_path, "variant": variant, "method": method,
                                                 "seed": args.seed + draw, **case.to_dict()})
                        rows.append(_case_row(name, method, case) | _basin_counts(case, *args.basin, beam))
                _print_idealized_table(f"{name} — method {method}: error mean±SD [RMSE] of converged starts", table,
                                       args.basin, beam)
    if len(rows) > 1:
        print(_totals_line(rows))
    _write_outputs(args.out, payload, rows)
    if args.json:
        print(json.dumps(payload))
    return 0


def _check_settings(args) -> None:
    """Refuse match settings no match can use (e.g. --outline-points 1) before any work."""
    for method in args.method:
        try:
            match_settings(args, method, multistart=False).validate()
        except ValueError as exc:
            raise UsageError(f"fluorogui: {exc}") from None


def _other_component(args):
    """(vertices, faces) of --other and whether it is the tibial component, or (None, True)."""
    if not args.other:
        return None, True
    role = args.other_is
    if role is None:
        name = Path(args.other).name.lower()
        role = "tibial" if "tib" in name else "femoral" if "fem" in name else None
        if role is None:
            raise UsageError(f"fluorogui: --other {args.other}: say which component it is "
                             "with --other-is tibial|femoral")
    mesh = load_model(args.other)
    return (mesh.vertices, mesh.faces), role == "tibial"


#: single-plane: the translation along the beam is weakly fixed by nature, so a start is in
#: the right basin with this much error along it (mm) when the rest is within --basin
SINGLE_VIEW_DEPTH_MM = 2.0


def _basin_counts(case, wrong_mm: float = WRONG_MM, wrong_deg: float = WRONG_DEG, beam=None) -> dict:
    """Starts in the right basin, converged ones, and converged ones in a wrong basin;
    ``beam`` (a single view's unit normal) allows ``SINGLE_VIEW_DEPTH_MM`` along it."""
    err = np.abs(np.asarray(case.errors, dtype=float)).reshape(-1, 6)
    if beam is None:
        right = (err[:, :3].max(1) <= wrong_mm) & (err[:, 3:].max(1) <= wrong_deg)
    else:
        signed = np.asarray(case.errors, dtype=float).reshape(-1, 6)[:, :3]
        along = signed @ np.asarray(beam, dtype=float)
        across = np.abs(signed - np.outer(along, beam)).max(1)
        right = (across <= wrong_mm) & (np.abs(along) <= SINGLE_VIEW_DEPTH_MM) & (err[:, 3:].max(1) <= wrong_deg)
    from fluorogui.core.projection.pose import pose_difference

    conv = np.array([r.converged for r in case.results], dtype=bool)
    # how far each start's pose parameters lie from the truth in its own reported SDs
    z = np.array([np.max(np.abs(pose_difference(r.pose, case.truth)) / np.maximum(r.sd, 1e-12))
                  if r.sd is not None else np.inf for r in case.results])
    return {"right_basin": int(right.sum()), "converged": int(conv.sum()),
            "false_converged": int((conv & ~right).sum()),
            "false_beyond_3sd": int((conv & ~right & (z > 3.0)).sum()),
            "worst_mm": round(float(err[:, :3].max()), 4), "worst_deg": round(float(err[:, 3:].max()), 4)}


def _totals_line(rows: list[dict]) -> str:
    """One line over all the cases of a run: starts in the right basin, converged ones
    outside it, the worst case's mean error (and the mean over cases of each case's
    largest mean error) and the worst start."""
    from fluorogui.simulation.protocols import DOF_LABELS

    means = np.array([[abs(r[f"{d}_mean"]) for d in DOF_LABELS] for r in rows], dtype=float)
    means = means[np.all(np.isfinite(means), axis=1)]  # a case without a converged start has no mean
    total = sum(r["n_runs"] for r in rows)
    line = (f"all {len(rows)} cases: {sum(r['right_basin'] for r in rows)}/{total} starts in the right basin, "
            f"{sum(r['false_converged'] for r in rows)} converged outside it "
            f"({sum(r['false_beyond_3sd'] for r in rows)} beyond 3 SD); ")
    if len(means):
        mm, deg = means[:, :3].max(axis=1), means[:, 3:].max(axis=1)
        line += (f"worst mean error {mm.max():.3f} mm / {deg.max():.3f} deg (mean over cases {mm.mean():.3f} mm / "
                 f"{deg.mean():.3f} deg); ")
    worst_mm, worst_deg = max(r["worst_mm"] for r in rows), max(r["worst_deg"] for r in rows)
    return line + f"worst start {worst_mm:.3f} mm / {worst_deg:.3f} deg\n"


def _print_idealized_table(title, table, basin=(WRONG_MM, WRONG_DEG), beam=None):
    """The paper's Table 1/2 layout plus, per case: converged starts, starts within
    ``basin`` (mm, deg) of the truth, converged starts outside it (and of those, the ones
    farther than 3 of their own reported SDs from the truth in some pose variable), and
    the worst start."""
    from fluorogui.simulation.protocols import DOF_LABELS

    print(title)
    head = f"{'case':<26}" + "".join(f"{d + (' (mm)' if k < 3 else ' (deg)'):>24}" for k, d in enumerate(DOF_LABELS))
    print(head + f"{'conv':>7}{'right':>7}{'false':>7}{'>3SD':>6}{'worst mm/deg':>15}{'s/match':>9}")
    for label, case in table:
        s, b = case.summary, _basin_counts(case, *basin, beam)
        print(f"{label:<26}" + "".join(f"{_fmt_dof(s, k):>24}" for k in range(6))
              + f"{b['converged']:>4}/{s.n_runs:<2}{b['right_basin']:>5}{b['false_converged']:>7}"
              + f"{b['false_beyond_3sd']:>6}"
              + f"{b['worst_mm']:>8.3f}/{b['worst_deg']:<6.3f}{s.median_seconds:>9.3f}")
    print()


def cmd_validate_spheres(args) -> int:
    from fluorogui.simulation.phantoms import sphere_mesh
    from fluorogui.simulation.protocols import SPHERE_DIAMETER, spheres_case

    check_output_folder(args.out)
    _check_settings(args)

    vertices, faces = sphere_mesh(SPHERE_DIAMETER)
    payload, rows = {"protocol": "spheres", "methods": {}}, []
    for method in args.method:
        settings = match_settings(args, method, multistart=False)
        settings.model_points = 2500
        if method == "paper" and args.outline_points is None:
            settings.outline_points = 60
        out = spheres_case(vertices, faces, settings, n_starts=args.starts, seed=args.seed)
        payload["methods"][method] = out
        print(f"spheres — method {method} (separation, mm; true {SPHERE_DIAMETER:.2f})")
        for name, m, s, r in zip(out["pairs"], out["pair_mean_mm"], out["pair_sd_mm"], out["pair_rmse_mm"]):
            print(f"  {name:<8} {m:8.3f} ± {s:.3f} [{r:.3f}]")
            rows.append({"method": method, "pair": name, "mean_mm": round(m, 5), "sd_mm": round(s, 5),
                         "rmse_mm": round(r, 5)})
        print(f"  mean {out['mean_mm']:.4f} (error {out['mean_error_mm']:+.4f}), SD {out['sd_mm']:.4f}, "
              f"RMSE {out['rmse_mm']:.4f}; {out['converged']}/{out['runs']} convergent, "
              f"median {out['median_seconds']:.3f} s/match\n")
    _write_outputs(args.out, payload, rows)
    if args.json:
        print(json.dumps(payload))
    return 0


def cmd_validate_repeatability(args) -> int:
    from fluorogui.core.matching.problem import MatchProblem
    from fluorogui.simulation.protocols import repeatability_case

    check_output_folder(args.out)
    _check_settings(args)

    views = load_views(args.camera)
    mesh = load_model(args.model)
    cases = []  # (label, image paths, pose)
    if args.reference:
        cases = _reference_cases(args)
    else:
        if args.pose is None:
            raise UsageError("fluorogui: give --pose (or --reference with --pairs)")
        cases = [("given pose", args.image, start_pose(args.pose, "--pose"))]
    payload, rows = {"protocol": "repeatability", "cases": []}, []
    for method in args.method:
        table = []
        for label, image_paths, pose in cases:
            splines = _case_splines(args, label, image_paths, views, mesh=mesh, pose=pose)
            settings = match_settings(args, method, multistart=False)
            case = repeatability_case(MatchProblem(mesh, views, splines), pose, settings, n_starts=args.starts,
                                      seed=args.seed,
                                      label=label)
            resid = case.extra["per_view_mean_mm"]
            table.append((f"{label} ({resid[0]:.2f}/{resid[1]:.2f})", case.summary))
            payload["cases"].append({"method": method, **case.to_dict()})
            rows.append(_case_row(args.model, method, case) | {"view1_mean_mm": round(resid[0], 4),
                                                                  "view2_mean_mm": round(resid[1], 4)})
        _print_table(f"{Path(args.model).name} — method {method}: spread about the mean pose, mean±SD [RMSE] "
                     "(label: mean outline residual per view, mm)", table)
        if len(table) > 1:
            sds = np.array([s.sd for _, s in table])
            print(f"worst SD over cases: translation {sds[:, :3].max():.3f} mm, rotation {sds[:, 3:].max():.3f} deg\n")
    _write_outputs(args.out, payload, rows)
    if args.json:
        print(json.dumps(payload))
    return 0


def _case_splines(args, label, image_paths, views, *, mesh, pose):
    """A case's outline splines: from --outline files, or segmented in its images. A problem
    with an image listed in --pairs names the pairs file too."""
    from fluorogui.io.errors import InputError

    try:
        images = load_images(image_paths, views)
        return outline_splines(args.outline if not args.reference else None, images, image_paths, views, mesh=mesh,
                               pose=pose)
    except InputError as exc:
        if not args.reference or exc.path not in map(str, image_paths):
            raise
        raise InputError(exc.path, f"{exc.problem} (listed in {args.pairs} for {label})") from None


def _reference_cases(args):
    from fluorogui.io.errors import InputError
    from fluorogui.io.importer import read_pairs_csv
    from fluorogui.io.pose_files import read_reference_poses

    if not args.pairs or not args.component:
        raise UsageError("fluorogui: --reference needs --pairs and --component")
    frames, paths = read_pairs_csv(args.pairs, 2)
    pairs = {str(frame): [str(paths[0][i]), str(paths[1][i])] for i, frame in enumerate(frames)}
    refs = read_reference_poses(args.reference, args.component)
    if not refs:
        raise InputError(args.reference, f"has no poses of the component {args.component!r}")
    cases = []
    for frame, _, pose in refs:
        if str(frame) not in pairs:
            raise InputError(args.reference, f"frame {frame} is not in {args.pairs}")
        cases.append((f"frame {frame}", pairs[str(frame)], start_pose(pose, f"{args.reference} frame {frame}")))
    return cases[: args.frames] if args.frames else cases


