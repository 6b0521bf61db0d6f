"""``fluorogui kinematics``: knee kinematics (Grood & Suntay) of a bare poses CSV from any
tool; with ``--contact`` / ``--pivot`` the condyles' contact on the tray
(``workflow.contact``); with ``--mean`` several projects' curves averaged
(``workflow.trials``)."""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from fluorogui.cli.common import UsageError, finite_float, warn
from fluorogui.cli.export import frame_list
from fluorogui.io.pose_files import read_frame_json

PROG = "fluorogui kinematics"
#: a lift-off threshold beyond this (mm) is a mistake: condyles are some 20 mm across
MAX_LIFTOFF_MM = 50.0


def liftoff_value(text: str) -> float:
    """An argparse type: a lift-off threshold above 0 and at most ``MAX_LIFTOFF_MM``."""
    import argparse

    value = finite_float(text)
    if not 0 < value <= MAX_LIFTOFF_MM:
        raise argparse.ArgumentTypeError(f"{value:g} is out of range; give more than 0 and at most "
                                         f"{MAX_LIFTOFF_MM:g} mm")
    return value


liftoff_value.__name__ = "threshold"


def add_parser(sub):
    k = sub.add_parser("kinematics", help="knee kinematics (Grood & Suntay) of poses from anywhere; condylar "
                                          "contact, pivot; trials averaged")
    k.add_argument("--poses", metavar="POSES.csv",
                   help="columns frame,component,x,y,z,alpha,beta,gamma (component femoral or tibial); required "
                        "unless --mean")
    k.add_argument("--side", choices=("right", "left"), help="the knee's side; required with --poses")
    k.add_argument("--femoral-frame", metavar="F.json", help='{"matrix": [[4 rows of 4]]}, anatomical -> model')
    k.add_argument("--tibial-frame", metavar="T.json")
    k.add_argument("--femoral-mesh", metavar="MESH", help="for the default femoral frame, and the femoral surface "
                                                          "of --contact / --pivot (STL, PLY, OBJ, VTK, VTP, STEP, "
                                                          "IGES)")
    k.add_argument("--tibial-mesh", metavar="MESH", help="for the default tibial frame")
    k.add_argument("--out", metavar="OUT.csv", help="the kinematics, one row per frame (with --mean: the averaged "
                                                    "curves)")
    k.add_argument("--contact", metavar="CONTACT.csv",
                   help="each condyle's lowest point on the tray (tibial frame, + lateral), its gap to the insert "
                        "and lift-off, one row per frame (needs --femoral-mesh)")
    k.add_argument("--insert-mesh", metavar="MESH", help="the insert (polyethylene) model, placed by the tray's "
                                                         "pose: gives the gaps and lift-off by gap")
    k.add_argument("--insert-frame", metavar="F.json",
                   help='{"matrix": [[4 rows of 4]]}, insert model -> tibial (tray) model; identity by default')
    k.add_argument("--liftoff-mm", type=liftoff_value, default=None, metavar="MM",
                   help="a condyle lifts off beyond this gap (without an insert: this much higher than the other "
                        "condyle); default 1.0")
    k.add_argument("--pivot", action="store_true",
                   help='print the pivot of axial rotation as one JSON line {"x_mm", "y_mm", "kind", "frames_used"} '
                        "(needs --femoral-mesh)")
    k.add_argument("--plot", metavar="OUT.png|svg|pdf",
                   help="the figure: with --contact or --pivot the contact plot, with --mean the averaged curves")
    k.add_argument("--mean", nargs="+", metavar="PROJECT.fluoro",
                   help="average these projects' kinematics and contact curves (mean and SD, each trial beside); "
                        "write them with --out and --plot")
    k.add_argument("--normalize", choices=("time", "flexion"), default=None,
                   help="with --mean: over 0-100%% of each trial's time (default), or by flexion angle")
    return k


load_frame_json = read_frame_json  # its old name


def _given(args, names) -> list[str]:
    return [f"--{n.replace('_', '-')}" for n in names if getattr(args, n) not in (None, False)]


def _check_outputs(args, paths) -> None:
    from fluorogui.io.files import check_output_file

    if args.plot and Path(args.plot).suffix.lower() not in (".png", ".svg", ".pdf"):
        raise UsageError(f"{PROG}: --plot {args.plot}: the figure must be .png, .svg or .pdf")
    for path in paths:  # before any work
        if path:
            check_output_file(path)


def _insert_matrix(args):
    if args.insert_frame and not args.insert_mesh:
        raise UsageError(f"{PROG}: --insert-frame places the --insert-mesh; give the mesh too")
    return load_frame_json(args.insert_frame) if args.insert_frame else None


def run(args) -> int:
    if args.mean:
        return run_mean(args)
    wrong = _given(args, ("normalize",))
    if wrong:
        raise UsageError(f"{PROG}: {wrong[0]} goes with --mean")
    missing = [name for name, value in (("--poses", args.poses), ("--side", args.side)) if not value]
    if missing:
        raise UsageError(f"{PROG}: the following arguments are required: {', '.join(missing)} (or --mean PROJECTS)")
    contact = bool(args.contact or args.pivot)
    if not (args.out or contact):
        raise UsageError(f"{PROG}: say what to write: --out (the kinematics), --contact or --pivot")
    stray = _given(args, ("insert_mesh", "insert_frame", "liftoff_mm", "plot"))
    if stray and not contact:
        raise UsageError(f"{PROG}: {stray[0]} goes with --contact or --pivot")
    if contact and not args.femoral_mesh:
        raise UsageError(f"{PROG}: --contact and --pivot need --femoral-mesh (the femoral surface)")
    _check_outputs(args, (args.out, args.contact, args.plot))
    frames, meshes = _anatomical_frames(args, contact)
    insert_to_tray = _insert_matrix(args)
    from fluorogui.io.pose_files import read_long_poses

    poses = read_long_poses(args.poses)
    said = []  # what was written; on stderr when stdout carries the --pivot JSON
    if args.out:
        said.append(_write_kinematics(args, poses, frames))
    if contact:
        said += _write_contact(args, poses, frames, meshes["femoral"], insert_to_tray)
    for line in said:
        print(line, file=sys.stderr if args.pivot else sys.stdout)
    return 0


def _anatomical_frames(args, femoral_surface: bool):
    """The two anatomical frames (from their JSON, else from the meshes) and the meshes read
    (the femoral one always when ``femoral_surface``)."""
    from fluorogui.core.knee.anatomy import default_frame
    from fluorogui.core.knee.kinematics import KinematicsError
    from fluorogui.io.errors import InputError
    from fluorogui.io.meshes.read import load_mesh

    frames, meshes = {}, {}
    for component, frame_path, mesh_path in (("femoral", args.femoral_frame, args.femoral_mesh),
                                             ("tibial", args.tibial_frame, args.tibial_mesh)):
        if mesh_path and (not frame_path or (component == "femoral" and femoral_surface)):
            meshes[component] = load_mesh(mesh_path)
        if frame_path:
            frames[component] = load_frame_json(frame_path)
        elif mesh_path:
            try:
                frames[component] = default_frame(component, *meshes[component])
            except KinematicsError as exc:
                raise InputError(mesh_path, f"no default anatomical frame: {exc}") from None
        else:
            raise UsageError(f"fluorogui: kinematics: give --{component}-frame or --{component}-mesh "
                             f"(the default {component} frame comes from the mesh)")
    return frames, meshes


def _write_kinematics(args, poses, frames) -> str:
    from fluorogui import __version__
    from fluorogui.core.knee.kinematics import KINEMATICS_COLUMNS, SIGN_CONVENTIONS
    from fluorogui.io.pose_files import write_csv
    from fluorogui.workflow.exports import kinematics_of_poses

    rows = kinematics_of_poses(poses, args.side, frames["femoral"], frames["tibial"])
    header = [f"fluorogui {__version__} knee kinematics of {Path(args.poses).name}",
              f"side: {args.side}", "units: mm and degrees", f"kinematics: {SIGN_CONVENTIONS}"]
    for component, matrix in frames.items():
        header.append(f"{component} anatomical frame (anatomical -> model): {json.dumps(matrix.round(9).tolist())}")
    header += [f"frame {frame}: NaN: {reason}" for frame, _, reason in rows if reason]
    write_csv(args.out, header, ["frame", *KINEMATICS_COLUMNS],
              [[frame, *(float(v) for v in values.values())] for frame, values, _ in rows])
    nan_rows = [frame for frame, _, reason in rows if reason]
    if nan_rows:
        warn(f"{len(nan_rows)} frame{'s' if len(nan_rows) > 1 else ''} written as NaN "
             f"({next(r for _, _, r in rows if r)}{', …' if len(nan_rows) > 1 else ''}): {frame_list(nan_rows)}")
    return f"wrote {args.out} ({len(rows)} frames)"


def _write_contact(args, poses, frames, femoral_mesh, insert_to_tray) -> list[str]:
    from fluorogui.core.knee.contact import LIFTOFF_MM
    from fluorogui.core.knee.kinematics import KinematicsError
    from fluorogui.io.errors import InputError
    from fluorogui.workflow.contact import (
        contact_of_poses,
        contact_setup,
        pivot_json,
        pivot_of_rows,
        write_contact_csv,
    )

    try:
        setup = contact_setup(femoral_mesh, femoral_frame=frames["femoral"], tibial_frame=frames["tibial"],
                              side=args.side, insert_mesh=args.insert_mesh, insert_to_tray=insert_to_tray,
                              liftoff_mm=args.liftoff_mm or LIFTOFF_MM)
        rows = contact_of_poses(poses, setup, frames["femoral"])
    except KinematicsError as exc:  # a femoral surface without two condyles, an insert without triangles
        raise InputError(args.femoral_mesh, f"no contact kinematics: {exc}") from None
    said = []
    if args.contact:
        write_contact_csv(args.contact, setup, rows, Path(args.poses).name)
        said.append(f"wrote {args.contact} ({len(rows)} frames)")
        missing = [r.frame for r in rows if r.status == "missing"]
        if missing and not args.out:  # --out has said so already
            warn(f"{len(missing)} frame{'s' if len(missing) > 1 else ''} written as NaN "
                 f"({next(r.reason for r in rows if r.status == 'missing')}"
                 f"{', …' if len(missing) > 1 else ''}): {frame_list(missing)}")
    found = pivot_of_rows(rows)
    if args.plot:
        from fluorogui.workflow.contact_plot import save_contact_figure

        save_contact_figure(rows, args.plot, side=args.side, title=Path(args.poses).stem, pivot=found)
        said.append(f"wrote {args.plot}")
    if args.pivot:
        if not math.isfinite(found.x_mm):
            warn(f"pivot not determined: {found.reason}")
        print(json.dumps(pivot_json(found)), flush=True)
    return said


def run_mean(args) -> int:
    """``--mean P1 P2 ...``: the projects' curves averaged into ``--out`` and ``--plot``."""
    from fluorogui.core.knee.contact import LIFTOFF_MM
    from fluorogui.core.knee.kinematics import KinematicsError
    from fluorogui.io.errors import InputError
    from fluorogui.workflow.session import Session
    from fluorogui.workflow.trials import average_trials, save_mean_plot, trial_of_session, write_mean_csv

    stray = _given(args, ("poses", "side", "femoral_frame", "tibial_frame", "femoral_mesh", "tibial_mesh", "contact",
                          "pivot"))
    if stray:
        raise UsageError(f"{PROG}: --mean averages projects, which hold their own poses, side, models and frames; "
                         f"it takes no {stray[0]}")
    if len(args.mean) < 2:
        raise UsageError(f"{PROG}: --mean needs two projects or more (got {len(args.mean)})")
    if not (args.out or args.plot):
        raise UsageError(f"{PROG}: --mean: say what to write: --out MEAN.csv, --plot MEAN.pdf or both")
    _check_outputs(args, (args.out, args.plot))
    insert_to_tray = _insert_matrix(args)
    trials = []
    for name in args.mean:
        path = Path(name)
        if not path.exists():
            raise InputError(path, "file not found")
        session = Session.open(path)
        try:
            trial = trial_of_session(session, name=path.name, insert_mesh=args.insert_mesh,
                                     insert_to_tray=insert_to_tray, liftoff_mm=args.liftoff_mm or LIFTOFF_MM)
        except KinematicsError as exc:
            raise InputError(path, f"no contact kinematics: {exc}") from None
        matched = int((trial.values == trial.values).any(axis=1).sum())
        if matched < 2:
            raise InputError(path, f"has {matched} matched frame{'' if matched == 1 else 's'}; a trial needs two "
                                   "or more to be averaged")
        if matched < len(trial.frames):
            warn(f"{path.name}: {len(trial.frames) - matched} of {len(trial.frames)} frames not matched, left out "
                 "of its curves")
        trials.append(trial)
    averaged = average_trials(trials, args.normalize or "time")
    if args.out:
        write_mean_csv(args.out, averaged)
        print(f"wrote {args.out} ({len(trials)} trials, {len(averaged.quantities)} curves)")
    if args.plot:
        save_mean_plot(args.plot, averaged)
        print(f"wrote {args.plot}")
    return 0
