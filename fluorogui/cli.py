"""Headless command line: match, bench, and (``fluorogui.commands``) validate, demo, import,
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
    add_rim_options,
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
    add_rim_options(m)
    m.add_argument("--json", action="store_true", help="print one JSON object")
    m.set_defaults(func=cmd_match)

    from fluorogui.commands import validate

    validate.add_parsers(sub)

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
                            "reason": result.message, "message": d["message"],
                            "rim_refined": result.settings.get("rim_refined", [False] * len(views))}))
    else:
        labels = ("x", "y", "z", "alpha", "beta", "gamma")
        print("pose: " + "  ".join(f"{l}={v:.4f}" for l, v in zip(labels, result.pose)))
        print("SD:   " + "  ".join(f"{l}={v:.4f}" for l, v in zip(labels, sd)))
        print(f"objective {result.objective_mm:.4f} mm (per view {', '.join(f'{v:.4f}' for v in result.per_view_mean_mm)}), "
              f"{result.calls} calls, {result.seconds:.3f} s, {'converged' if result.converged else 'NOT converged: ' + result.message}")
        from fluorogui.workflow.messages import rim_note

        note = rim_note(result.settings)
        if note:
            print(note)
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
