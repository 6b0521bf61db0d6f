"""Headless command line: match, validate, bench, and (``fluorogui.commands``) demo, import,
find, track and batch over the workflow. Never imports Qt.

Every failure ends in one line on stderr and a non-zero exit (2 for bad input, 1 for
an internal error), never a traceback.
"""
from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fluorogui import __version__
from fluorogui.commands.common import (
    UsageError,
    check_output_folder,
    finite_float,
    int_in,
    native_stderr_to_log,
)


# ranges of the numeric options (the matcher checks what a method needs beyond them)
STARTS_RANGE = (1, 1000)
POINTS_RANGE = (10, 5_000_000)
OUTLINE_POINTS_RANGE = (1, 100_000)
SEED_RANGE = (0, 2**32 - 1)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, not usage + message
        raise _UsageError(f"{self.prog}: {message}")


class _UsageError(Exception):
    pass


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="fluorogui", description="Pose of knee-implant components from biplane fluoroscopy.")
    p.add_argument("--version", action="version", version=f"fluorogui {__version__}")
    p.add_argument("--verbose", action="store_true",
                   help="also print warnings of the libraries (VTK, image readers) and tracebacks on the terminal")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)

    m = sub.add_parser("match", help="match one component in one image pair")
    m.add_argument("--camera", action="append", required=True, metavar="CAM", help="calibration file (twice; once for single-plane)")
    m.add_argument("--image", action="append", required=True, metavar="IMG",
                   help="image file per camera; FILE@N is frame N (0-based) of a multi-frame DICOM or video")
    m.add_argument("--model", required=True, metavar="MESH", help="component mesh in mm (STL/PLY/OBJ/VTK)")
    m.add_argument("--start", nargs=6, type=finite_float, required=True, metavar=("X", "Y", "Z", "ALPHA", "BETA", "GAMMA"))
    m.add_argument("--outline", action="append", metavar="CSV", help="ordered outline points u,v (twice)")
    m.add_argument("--correction", action="append", metavar="CORR.json",
                   help="distortion correction per camera (fluorogui calibrate distortion)")
    _add_match_options(m)
    m.add_argument("--rim", action="store_true",
                   help="automatic outlines: move them to the boundary the metal's rim profile gives (core.rim)")
    m.add_argument("--json", action="store_true", help="print one JSON object")
    m.set_defaults(func=cmd_match)

    v = sub.add_parser("validate", help="the paper's validation protocols")
    vs = v.add_subparsers(dest="protocol", parser_class=_Parser, required=True)
    vi = vs.add_parser("idealized", help="Tables 1/2: rendered images of a model at flexion poses")
    vi.add_argument("--model", action="append", required=True, metavar="MESH")
    vi.add_argument("--flexion", nargs="+", type=finite_float, default=[30.0, 45.0, 60.0, 90.0])
    vi.add_argument("--density", nargs="+", type=int_in(*POINTS_RANGE), default=[15000],
                    help="point-model sizes (paper method)")
    vi.add_argument("--renderer", choices=["xray", "silhouette"], default="xray",
                    help="xray: the independent image model (default); silhouette: the old filled silhouette")
    vi.add_argument("--variant", nargs="+", default=[""], metavar="V",
                    help="mesh variants: none, mirrored, scaled+15, scaled-15")
    vi.add_argument("--angle", type=finite_float, default=90.0, help="degrees between the two views")
    vi.add_argument("--tilt", type=finite_float, default=0.0, help="degrees the views are tilted out of a common plane")
    vi.add_argument("--offset", nargs=2, type=finite_float, default=[0.0, 0.0], metavar=("DU", "DV"),
                    help="principal point offset (px): the object off the image centre")
    vi.add_argument("--source-distance", nargs=2, type=finite_float, default=[1000.0, 1000.0], metavar=("D1", "D2"),
                    help="source to object distance per view (mm)")
    vi.add_argument("--bits", type=int, choices=[8, 16], default=16, help="xray: image bit depth")
    vi.add_argument("--mu", type=finite_float, default=None, help="xray: the metal's attenuation (1/mm; default CoCr, 1.0)")
    vi.add_argument("--image-size", type=int, default=1024, help="image width and height (px; same field of view)")
    vi.add_argument("--distortion", type=finite_float, default=0.0, metavar="K1",
                    help="xray: radial distortion applied to the images, then corrected before matching")
    _add_validation_options(vi)
    vi.set_defaults(func=cmd_validate_idealized)
    vp = vs.add_parser("spheres", help="Table 3: eight stacked 12.70 mm spheres")
    _add_validation_options(vp)
    vp.set_defaults(func=cmd_validate_spheres)
    vr = vs.add_parser("repeatability", help="Table 4: perturbed starts of a given pose on real images")
    vr.add_argument("--camera", action="append", required=True, metavar="CAM")
    vr.add_argument("--image", action="append", metavar="IMG")
    vr.add_argument("--model", required=True, metavar="MESH")
    vr.add_argument("--pose", nargs=6, type=finite_float, metavar=("X", "Y", "Z", "ALPHA", "BETA", "GAMMA"))
    vr.add_argument("--outline", action="append", metavar="CSV")
    vr.add_argument("--reference", metavar="CSV", help="poses per frame: frame,component,x,y,z,alpha,beta,gamma")
    vr.add_argument("--pairs", metavar="CSV", help="with --reference: frame,cam1,cam2 image pairs")
    vr.add_argument("--component", help="with --reference: the component of --model")
    vr.add_argument("--frames", type=int_in(0, 1_000_000), default=0, help="with --reference: first N frames (0 = all)")
    _add_validation_options(vr)
    vr.set_defaults(func=cmd_validate_repeatability)

    b = sub.add_parser("bench", help="time matches of both methods on the real implant meshes")
    b.add_argument("--model", action="append", metavar="MESH", help="default: the meshes in ../shared/data")
    b.add_argument("--method", nargs="+", choices=["fast", "paper"], default=["fast", "paper"])
    b.add_argument("--starts", type=int_in(*STARTS_RANGE), default=10)
    b.add_argument("--points", type=int_in(*POINTS_RANGE), default=15000)
    b.add_argument("--outline-points", type=int_in(*OUTLINE_POINTS_RANGE), default=60)
    b.add_argument("--seed", type=int_in(*SEED_RANGE), default=0)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench)

    from fluorogui.commands import add_parsers

    add_parsers(sub)
    from fluorogui.commands import calibrate

    calibrate.add_parsers(sub)
    return p


def _add_match_options(p):
    p.add_argument("--points", type=int_in(*POINTS_RANGE), default=15000, help="point-model size (paper method)")
    p.add_argument("--outline-points", type=int_in(*OUTLINE_POINTS_RANGE), default=None, help="outline points per view (paper default 60)")
    p.add_argument("--method", choices=["fast", "paper"], default="fast")
    p.add_argument("--starts", type=int_in(*STARTS_RANGE), default=1, help="independent starts; the best match is kept")


def _add_validation_options(p):
    p.add_argument("--method", nargs="+", choices=["fast", "paper"], default=["fast"])
    p.add_argument("--starts", type=int_in(*STARTS_RANGE), default=10, help="perturbed starts per case")
    p.add_argument("--outline-points", type=int_in(*OUTLINE_POINTS_RANGE), default=None)
    p.add_argument("--seed", type=int_in(*SEED_RANGE), default=0)
    p.add_argument("--out", metavar="DIR", help="write results.json and results.csv here")
    p.add_argument("--json", action="store_true", help="print the results as JSON")


# -- helpers --------------------------------------------------------------------------------
def _load_views(paths):
    from fluorogui.io.calibration import load_view

    if len(paths) not in (1, 2):
        raise _UsageError(f"fluorogui: give two --camera files, or one for a single-plane view (got {len(paths)})")
    return [load_view(p, name=f"view {k + 1}") for k, p in enumerate(paths)]


def _with_corrections(views, paths):
    """The views carrying their distortion corrections (one file per view), if any."""
    from fluorogui.io.corrections import attach_correction, load_correction

    if not paths:
        return views
    if len(paths) != len(views):
        raise _UsageError(f"fluorogui: give one --correction per --camera ({len(views)}), got {len(paths)}")
    return [attach_correction(v, load_correction(p)) for v, p in zip(views, paths)]


def _load_images(paths, views):
    from fluorogui.io.calibration import check_image_size
    from fluorogui.io.corrections import correct_view_image
    from fluorogui.io.images import read_image

    if len(paths or []) != len(views):
        raise _UsageError(f"fluorogui: give one --image per --camera ({len(views)}), got {len(paths or [])}; "
                          "FILE@N picks frame N of a multi-frame DICOM or video")
    images = []
    for p, v in zip(paths, views):
        image = read_image(p)
        check_image_size(v, image.shape, p)
        images.append(correct_view_image(image, v))
    return images


def _load_model(path):
    from fluorogui.core.mesh import MeshError, check_plausible_mm, prepare_mesh
    from fluorogui.io.errors import InputError
    from fluorogui.io.meshes import load_mesh

    vertices, faces = load_mesh(path)
    try:
        check_plausible_mm(vertices)
        return prepare_mesh(vertices, faces)
    except MeshError as exc:
        raise InputError(path, str(exc)) from None


def _start_pose(values, what="--start"):
    from fluorogui.core.pose import as_pose

    try:
        return as_pose(values)
    except ValueError as exc:
        raise _UsageError(f"fluorogui: {what}: {exc}") from None


def _splines(outline_paths, images, image_paths, views, mesh, pose):
    """Splines from given outline files, or segmented from the images near the pose."""
    from fluorogui.core.edges import component_outline
    from fluorogui.core.pipeline import predicted_outline
    from fluorogui.core.spline import OutlineError, OutlineSpline
    from fluorogui.io.errors import InputError
    from fluorogui.io.outlines import read_outline_csv

    if outline_paths and len(outline_paths) != len(views):
        raise _UsageError(f"fluorogui: give one --outline per view or none (got {len(outline_paths)})")
    splines = []
    for k, view in enumerate(views):
        if outline_paths:
            source, points = outline_paths[k], read_outline_csv(outline_paths[k])
        else:
            source = image_paths[k]
            try:
                points = component_outline(images[k], predicted_outline(mesh, pose, view))
            except ValueError as exc:
                raise InputError(source, f"no outline of the component found near the start pose ({exc})") from None
        try:
            splines.append(OutlineSpline.fit(points))
        except (OutlineError, ValueError) as exc:
            raise InputError(source, str(exc)) from None
    return splines


def _settings(args, method=None, multistart: bool = True):
    """Match settings from the options; validations pass ``multistart=False`` because their
    --starts counts perturbed starts, each one match."""
    from fluorogui.core.matching import MatchSettings

    method = method or args.method
    outline_points = args.outline_points
    if method == "paper" and outline_points is None:
        outline_points = 60
    return MatchSettings(method=method, model_points=getattr(args, "points", 15000),
                         outline_points=outline_points,
                         starts=max(1, getattr(args, "starts", 1)) if multistart else 1)


def _write_outputs(out_dir, payload: dict, rows: list[dict]):
    from fluorogui.io.errors import atomic_write_text

    if not out_dir:
        return
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "results.json", json.dumps(payload, indent=2))
    if rows:
        keys = list(rows[0].keys())
        lines = [",".join(keys)] + [",".join(str(r[k]) for k in keys) for r in rows]
        atomic_write_text(out / "results.csv", "\n".join(lines) + "\n")
    print(f"wrote {out / 'results.json'} and {out / 'results.csv'}")


def _fmt_dof(summary, k):
    return f"{summary.mean[k]:+.3f}±{summary.sd[k]:.3f} [{summary.rmse[k]:.3f}]"


def _print_table(title, rows):
    """rows: (label, Summary)."""
    from fluorogui.core.validation import DOF_LABELS

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
    from fluorogui.core.validation import DOF_LABELS

    for k, d in enumerate(DOF_LABELS):
        row[f"{d}_mean"], row[f"{d}_sd"], row[f"{d}_rmse"] = (round(float(x), 5) for x in (s.mean[k], s.sd[k], s.rmse[k]))
    return row


# -- commands ---------------------------------------------------------------------------------
def cmd_match(args) -> int:
    from fluorogui.core.matching import MatchProblem, match
    from fluorogui.core.pipeline import LoopSettings, SegmentationError, segment_and_match
    from fluorogui.io.errors import InputError

    views = _with_corrections(_load_views(args.camera), args.correction)
    images = _load_images(args.image, views)
    mesh = _load_model(args.model)
    start = _start_pose(args.start)
    settings = _settings(args)
    try:
        settings.validate()
    except ValueError as exc:
        raise _UsageError(f"fluorogui: {exc}") from None
    _check_start_visible(views, mesh, start, args.image)
    if args.outline:
        splines = _splines(args.outline, images, args.image, views, mesh, start)
        result = match(MatchProblem(mesh, views, splines), start, settings)
    else:
        # the one segment -> match -> re-segment loop of the app and of tracking
        try:
            outcome = segment_and_match(images, views, mesh, start, settings, LoopSettings(rim=args.rim))
        except SegmentationError as exc:
            raise InputError(args.image[exc.view],
                             f"no outline of the component found near the start pose ({exc.reason})") from None
        result, splines = outcome.result, outcome.splines
    status, reason = _judge_on_images(images, views, mesh, result, splines)
    if status != "matched" and result.converged:
        result.converged, result.message = False, reason
    sd = result.sd or [float("nan")] * 6
    if len(views) == 1:
        from fluorogui.workflow.messages import SINGLE_PLANE_NOTE

        print(f"note: {SINGLE_PLANE_NOTE}", file=sys.stderr)
    if args.json:
        d = result.to_dict()
        print(json.dumps({k: d[k] for k in ("pose", "objective_mm", "per_view_mean_mm", "calls", "seconds",
                                              "converged", "method")}
                         | {"sd": [v if np.isfinite(v) else None for v in sd], "status": status,
                            "reason": result.message, "message": d["message"]}))
    else:
        labels = ("x", "y", "z", "alpha", "beta", "gamma")
        print("pose: " + "  ".join(f"{l}={v:.4f}" for l, v in zip(labels, result.pose)))
        print("SD:   " + "  ".join(f"{l}={v:.4f}" for l, v in zip(labels, sd)))
        print(f"objective {result.objective_mm:.4f} mm (per view {', '.join(f'{v:.4f}' for v in result.per_view_mean_mm)}), "
              f"{result.calls} calls, {result.seconds:.3f} s, {'converged' if result.converged else 'NOT converged: ' + result.message}")
    return 0 if result.converged else 3


def _check_start_visible(views, mesh, start, image_paths) -> None:
    """Refuse a start pose that puts the component (its centroid) outside an image: the
    outline there cannot be segmented or matched."""
    from fluorogui.core.pose import transform_points
    from fluorogui.io.errors import InputError

    centre = transform_points(start, mesh.centroid[None, :])
    for path, view in zip(image_paths, views):
        depth = float((centre[0] - view.source) @ view.normal)
        uv = view.project(centre)[0] if depth > 0 else np.array([np.nan, np.nan])
        w, h = view.image_size
        if not (depth > 0 and 0 <= uv[0] <= w - 1 and 0 <= uv[1] <= h - 1):
            raise InputError(path, "the start pose puts the component outside this image "
                                   f"(its centre projects to u={uv[0]:.0f}, v={uv[1]:.0f}; image {w}x{h})")


def _judge_on_images(images, views, mesh, result, splines) -> tuple[str, str]:
    """The tracking's quality checks (``core.quality``) on a single match: residual per
    view, model outline on image edges, image outline on the model, field of view."""
    from fluorogui.core.quality import assess, judge
    from fluorogui.core.shape_search import image_field

    outlines = [sp.sample(max(64, int(sp.length_px)), skip_gaps=True) for sp in splines]
    fields = [image_field(image, margin_px=2) for image in images]
    quality = assess(images, views, mesh, result.pose, result.converged, result.per_view_mean_mm, outlines,
                     fields=fields, model_outlines=result.outlines_px)
    return judge(quality, view_names=[f"view {k + 1}" for k in range(len(views))])


def _xray_renderer(args):
    """The independent image model as ``idealized_case``'s renderer (None: the old one)."""
    if args.renderer != "xray":
        return None
    from fluorogui.validation.xray import MU_METAL, Body, XrayModel, undistort_image, xray_image

    model = XrayModel(bits=args.bits, distortion_k1=args.distortion)
    mu = args.mu or MU_METAL

    def render(view, meshes, rng):
        image = xray_image(view, [Body(v, f, mu) for v, f in meshes], model, rng)
        return undistort_image(image, args.distortion) if args.distortion else image

    return render


#: a start ending farther than this from the truth (mm, deg) is in a wrong basin
WRONG_MM, WRONG_DEG = 0.05, 0.05


def cmd_validate_idealized(args) -> int:
    from fluorogui.core.validation import idealized_case, mesh_variant, two_views

    check_output_folder(args.out)
    if not 64 <= args.image_size <= 4096:
        raise _UsageError(f"fluorogui: --image-size {args.image_size}: give 64 to 4096 pixels")
    views = two_views(args.angle, args.tilt, tuple(args.offset), tuple(args.source_distance),
                      image_size=(args.image_size, args.image_size), pitch=315.0 / args.image_size)
    render = _xray_renderer(args)
    print(f"idealized: {args.renderer} images, views {args.angle:g} deg apart, tilt {args.tilt:g} deg, "
          f"offset {args.offset[0]:g}/{args.offset[1]:g} px, sources {args.source_distance[0]:g}/"
          f"{args.source_distance[1]:g} mm" + (f", {args.bits}-bit, metal {args.mu or 1.0:g}/mm, distortion k1 {args.distortion:g} (corrected)"
                                                  if render else "") + f"; {args.starts} starts per case\n")
    payload, rows = {"protocol": "idealized", "renderer": args.renderer, "cases": []}, []
    for model_path in args.model:
        base = _load_model(model_path)
        for variant in [v if v != "none" else "" for v in args.variant]:
            try:
                vertices, faces = mesh_variant(base.vertices, base.faces, variant)
            except ValueError as exc:
                raise _UsageError(f"fluorogui: --variant: {exc}") from None
            name = Path(model_path).name + (f" ({variant})" if variant else "")
            for method in args.method:
                table = []
                densities = args.density if method == "paper" else [None]
                for density in densities:
                    for flexion in args.flexion:
                        settings = _settings(args, method, multistart=False)
                        if density:
                            settings.model_points = density
                        label = f"{flexion:g} deg" + (f", {density} pts" if density else "")
                        case = idealized_case(vertices, faces, flexion, settings, args.starts, args.seed,
                                              views=views, label=label, render=render)
                        table.append((label, case))
                        payload["cases"].append({"model": model_path, "variant": variant, "method": method,
                                                 **case.to_dict()})
                        rows.append(_case_row(name, method, case) | _basin_counts(case))
                _print_idealized_table(f"{name} — method {method}: error mean±SD [RMSE] of converged starts", table)
    _write_outputs(args.out, payload, rows)
    if args.json:
        print(json.dumps(payload))
    return 0


def _basin_counts(case) -> dict:
    """Starts in the right basin, converged ones, and converged ones in a wrong basin."""
    err = np.abs(np.asarray(case.errors, dtype=float)).reshape(-1, 6)
    right = (err[:, :3].max(1) <= WRONG_MM) & (err[:, 3:].max(1) <= WRONG_DEG)
    conv = np.array([r.converged for r in case.results], dtype=bool)
    return {"right_basin": int(right.sum()), "converged": int(conv.sum()), "false_converged": int((conv & ~right).sum()),
            "worst_mm": round(float(err[:, :3].max()), 4), "worst_deg": round(float(err[:, 3:].max()), 4)}


def _print_idealized_table(title, table):
    """The paper's Table 1/2 layout plus, per case: converged starts, starts within
    0.05 mm / 0.05 deg of the truth, converged starts outside it, and the worst start."""
    from fluorogui.core.validation import DOF_LABELS

    print(title)
    head = f"{'case':<14}" + "".join(f"{d + (' (mm)' if k < 3 else ' (deg)'):>24}" for k, d in enumerate(DOF_LABELS))
    print(head + f"{'conv':>7}{'right':>7}{'false':>7}{'worst mm/deg':>15}{'s/match':>9}")
    for label, case in table:
        s, b = case.summary, _basin_counts(case)
        print(f"{label:<14}" + "".join(f"{_fmt_dof(s, k):>24}" for k in range(6))
              + f"{b['converged']:>4}/{s.n_runs:<2}{b['right_basin']:>5}{b['false_converged']:>7}"
              + f"{b['worst_mm']:>8.3f}/{b['worst_deg']:<6.3f}{s.median_seconds:>9.3f}")
    print()


def cmd_validate_spheres(args) -> int:
    from fluorogui.core.phantoms import sphere_mesh
    from fluorogui.core.validation import SPHERE_DIAMETER, spheres_case

    check_output_folder(args.out)

    vertices, faces = sphere_mesh(SPHERE_DIAMETER)
    payload, rows = {"protocol": "spheres", "methods": {}}, []
    for method in args.method:
        settings = _settings(args, method, multistart=False)
        settings.model_points = 2500
        if method == "paper" and args.outline_points is None:
            settings.outline_points = 60
        out = spheres_case(vertices, faces, settings, args.starts, args.seed)
        payload["methods"][method] = out
        print(f"spheres — method {method} (separation, mm; true {SPHERE_DIAMETER:.2f})")
        for name, m, s, r in zip(out["pairs"], out["pair_mean_mm"], out["pair_sd_mm"], out["pair_rmse_mm"]):
            print(f"  {name:<8} {m:8.3f} ± {s:.3f} [{r:.3f}]")
            rows.append({"method": method, "pair": name, "mean_mm": round(m, 5), "sd_mm": round(s, 5), "rmse_mm": round(r, 5)})
        print(f"  mean {out['mean_mm']:.4f} (error {out['mean_error_mm']:+.4f}), SD {out['sd_mm']:.4f}, RMSE {out['rmse_mm']:.4f}; "
              f"{out['converged']}/{out['runs']} convergent, median {out['median_seconds']:.3f} s/match\n")
    _write_outputs(args.out, payload, rows)
    if args.json:
        print(json.dumps(payload))
    return 0


def cmd_validate_repeatability(args) -> int:
    from fluorogui.core.matching import MatchProblem
    from fluorogui.core.validation import repeatability_case

    check_output_folder(args.out)

    views = _load_views(args.camera)
    mesh = _load_model(args.model)
    cases = []  # (label, image paths, pose)
    if args.reference:
        cases = _reference_cases(args)
    else:
        if args.pose is None:
            raise _UsageError("fluorogui: give --pose (or --reference with --pairs)")
        cases = [("given pose", args.image, _start_pose(args.pose, "--pose"))]
    payload, rows = {"protocol": "repeatability", "cases": []}, []
    for method in args.method:
        table = []
        for label, image_paths, pose in cases:
            images = _load_images(image_paths, views)
            splines = _splines(args.outline if not args.reference else None, images, image_paths, views, mesh, pose)
            case = repeatability_case(MatchProblem(mesh, views, splines), pose, _settings(args, method, multistart=False), args.starts,
                                      args.seed, label=label)
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


def _reference_cases(args):
    from fluorogui.io.errors import InputError
    from fluorogui.io.importer import read_pairs_csv
    from fluorogui.io.tables import read_reference_poses

    if not args.pairs or not args.component:
        raise _UsageError("fluorogui: --reference needs --pairs and --component")
    frames, paths = read_pairs_csv(args.pairs, 2)
    pairs = {str(frame): [str(paths[0][i]), str(paths[1][i])] for i, frame in enumerate(frames)}
    refs = read_reference_poses(args.reference, args.component)
    if not refs:
        raise InputError(args.reference, f"has no poses of the component {args.component!r}")
    cases = []
    for frame, _, pose in refs:
        key = str(int(frame)) if frame.strip().lstrip("-").isdigit() else frame
        if key not in pairs:
            raise InputError(args.reference, f"frame {frame} is not in {args.pairs}")
        cases.append((f"frame {frame}", pairs[key], _start_pose(pose, f"{args.reference} frame {frame}")))
    return cases[: args.frames] if args.frames else cases


def _default_bench_models():
    data = Path(__file__).resolve().parents[1].parent / "shared" / "data"
    found = sorted(data.glob("*/models/*.stl")) + sorted(data.glob("single-plane-tka/*.stl"))
    return [str(p) for p in found]


def cmd_bench(args) -> int:
    from fluorogui.core.matching import MatchSettings
    from fluorogui.core.validation import idealized_case

    models = args.model or _default_bench_models()
    if not models:
        raise _UsageError("fluorogui: no meshes given and none found in ../shared/data; use --model")
    print(f"bench: {args.starts} starts within ±20 mm / ±20 deg per model, {args.points} model points (paper), "
          f"{args.outline_points} outline points, rendered images at 45 deg flexion\n")
    print(f"{'model':<28}{'method':<8}{'median s':>10}{'min s':>9}{'max s':>9}{'ms/call':>9}{'calls':>7}{'conv':>6}")
    payload = []
    for model_path in models:
        mesh = _load_model(model_path)
        for method in args.method:
            settings = MatchSettings(method=method, model_points=args.points, outline_points=args.outline_points)
            case = idealized_case(mesh.vertices, mesh.faces, 45.0, settings, args.starts, args.seed)
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


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; every failure ends in one line on stderr: exit 2 for bad input (the
    line names the file or option), 1 for an internal error (its traceback in the log file)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    verbose = "--verbose" in argv
    argv = [a for a in argv if a != "--verbose"]  # allowed anywhere on the line
    from fluorogui.logs import setup_logging

    log_path = setup_logging(verbose=verbose)
    try:
        with native_stderr_to_log(None if verbose else log_path):
            return _run(argv)
    except (_UsageError, UsageError) as exc:
        print(str(exc), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fluorogui: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - the CLI never shows a traceback
        from fluorogui.core.geometry import GeometryError
        from fluorogui.core.mesh import MeshError
        from fluorogui.io.errors import InputError
        from fluorogui.logs import log_exception

        if isinstance(exc, OSError) and exc.filename and not isinstance(exc, InputError):
            from fluorogui.io.errors import describe_os_error

            exc = InputError(exc.filename, describe_os_error(exc))  # a path we could not read or write
        if isinstance(exc, InputError):
            print(f"fluorogui: error: {exc}", file=sys.stderr)
            return 2
        logged = log_exception(f"fluorogui {' '.join(argv)[:500]}")
        if isinstance(exc, (GeometryError, MeshError, ValueError, KeyError)):
            if isinstance(exc, KeyError):
                exc = exc.args[0] if exc.args else exc
            print(f"fluorogui: error: {' '.join(str(exc).split())}", file=sys.stderr)
            return 2
        where = f"; details in {logged}" if logged else ""
        print(f"fluorogui: internal error: {type(exc).__name__}: {' '.join(str(exc).split())[:300]}{where}",
              file=sys.stderr)
        return 1


def _run(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    if not getattr(args, "command", None):
        build_parser().print_help()
        return 0
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
