"""``fluorogui match``: one component in one image pair, through the same per-frame matcher
as tracking, ``Session.match`` and the app's *Match* (recovery, the ambiguity probe,
occlusion masks, the rim judgement and every quality check). Its JSON object is a
contract (``docs/cli/match.rst``)."""
from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from fluorogui.cli import inputs
from fluorogui.cli.common import (
    Numbers,
    UsageError,
    add_match_options,
    add_quality_option,
    add_rim_options,
    finite_float,
    quality_thresholds,
)


def add_parser(sub):
    m = sub.add_parser("match", help="match one component in one image pair")
    m.add_argument("--camera", action="append", required=True, metavar="CAM",
                   help="calibration file (twice; once for single-plane)")
    m.add_argument("--image", action="append", required=True, metavar="IMG",
                   help="image file per camera; FILE@N is frame N (0-based) of a multi-frame DICOM or video")
    m.add_argument("--model", required=True, metavar="MESH", help="component mesh in mm (STL/PLY/OBJ/VTK)")
    m.add_argument("--start", action=Numbers, type=finite_float, required=True,
                   metavar=("X", "Y", "Z", "ALPHA", "BETA", "GAMMA"),
                   help="the start pose: mm and degrees (angles within ±360)")
    m.add_argument("--outline", action="append", metavar="CSV", help="ordered outline points u,v (twice)")
    m.add_argument("--correction", action="append", metavar="CORR.json",
                   help="distortion correction per camera (fluorogui calibrate distortion)")
    m.add_argument("--component", metavar="NAME",
                   help="the component's name in messages (default: femoral / tibial from the mesh file's name)")
    m.add_argument("--other", metavar="MESH", help="the knee's other component, at --other-pose: where its "
                   "projection overlaps this one it is masked out, as the app and tracking do")
    m.add_argument("--other-pose", action=Numbers, type=finite_float,
                   metavar=("X", "Y", "Z", "ALPHA", "BETA", "GAMMA"))
    add_match_options(m)
    add_rim_options(m)
    add_quality_option(m, "the defaults")
    m.add_argument("--json", action="store_true", help="print one JSON object")
    return m


def component_name(path, taken: str = "") -> str:
    """The component a mesh file is, from its name (femoral / tibial), else "component"."""
    name = Path(path).name.lower()
    guess = "tibial" if "tib" in name else "femoral" if "fem" in name else "component"
    return guess if guess != taken else f"other {guess}"


def run(args) -> int:
    from fluorogui.core.status import Status
    from fluorogui.workflow.session import Session
    from fluorogui.workflow.settings import WorkflowSettings

    views = inputs.with_corrections(inputs.load_views(args.camera), args.correction)
    if len(args.image or []) != len(views):
        raise UsageError(f"fluorogui: give one --image per --camera ({len(views)}), got {len(args.image or [])}; "
                         "FILE@N picks frame N of a multi-frame DICOM or video")
    if args.outline and len(args.outline) != len(views):
        raise UsageError(f"fluorogui: give one --outline per view or none (got {len(args.outline)})")
    if (args.other is None) != (args.other_pose is None):
        raise UsageError("fluorogui: --other and --other-pose go together")
    settings = WorkflowSettings()
    settings.match = inputs.match_settings(args)
    settings.loop.rim = args.rim
    settings.quality = quality_thresholds(args.quality, settings.quality)
    try:
        settings.match.validate()
    except ValueError as exc:
        raise UsageError(f"fluorogui: {exc}") from None
    images = inputs.load_images(args.image, views)  # a damaged or blank image refused before any work
    component = args.component or component_name(args.model)
    models = {component: args.model}
    if args.other:
        other = component_name(args.other, taken=component)
        models[other] = args.other
    session = Session.of_images(views, args.image, models)
    session.set_settings(settings)
    start = inputs.start_pose(args.start)
    inputs.check_start_visible(views, session.mesh(component), start, args.image)
    session.set_pose(component, 0, start)
    if args.other:
        session.mesh(other)
        session.set_pose(other, 0, inputs.start_pose(args.other_pose, "--other-pose"))
    for k, path in enumerate(args.outline or []):
        session.set_outline((0, k, component), inputs.read_outline(path, views[k]), "Outline file", reviewed=True)
    # the session's own match, handed the images read above (read once, not twice)
    results = replace(session.match_job(0, component), images=images).run()
    session.store(results)
    result = results[0]
    if len(views) == 1:
        from fluorogui.workflow.messages import SINGLE_PLANE_NOTE

        print(f"note: {SINGLE_PLANE_NOTE}", file=sys.stderr)
    matched = result.status == Status.MATCHED
    m = result.match
    sd = (m.sd if m is not None and m.sd is not None else None) or [float("nan")] * 6
    message = (m.message if m is not None else "") or ("" if matched else result.reason)
    pose = np.asarray(result.pose, dtype=float)
    if args.json:
        print(json.dumps({
            "pose": [float(v) for v in pose],
            "objective_mm": None if m is None else float(m.objective_mm),
            "per_view_mean_mm": None if m is None else [float(v) for v in m.per_view_mean_mm],
            "calls": 0 if m is None else int(m.calls),
            "seconds": float(result.seconds),
            "converged": matched,
            "method": settings.match.method,
            "sd": [float(v) if np.isfinite(v) else None for v in sd],
            "status": str(result.status),
            "reason": result.reason,
            "message": message,
            "rim_refined": [bool(v) for v in (m.settings.get("rim_refined", []) if m is not None else [])]
            or [False] * len(views),
        }))
    else:
        labels = ("x", "y", "z", "alpha", "beta", "gamma")
        print("pose: " + "  ".join(f"{name}={v:.4f}" for name, v in zip(labels, pose)))
        print("SD:   " + "  ".join(f"{name}={v:.4f}" for name, v in zip(labels, sd)))
        if m is not None:
            print(f"objective {m.objective_mm:.4f} mm (per view {', '.join(f'{v:.4f}' for v in m.per_view_mean_mm)}), "
                  f"{m.calls} calls, {result.seconds:.3f} s, "
                  f"{'converged' if matched else 'NOT converged: ' + result.reason}")
            from fluorogui.workflow.messages import rim_note

            note = rim_note(m.settings)
            if note:
                print(note)
        else:
            print(f"{result.status.replace('_', ' ')}: {result.reason}")
    return 0 if matched else 3
