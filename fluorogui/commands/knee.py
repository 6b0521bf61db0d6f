"""``fluorogui export`` (poses, kinematics, .tra, .jts and the figure of a project) and
``fluorogui kinematics`` (joint kinematics of a bare poses CSV), over
``fluorogui.workflow.exports``."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from fluorogui.commands.common import UsageError, warn


def add_parsers(sub) -> None:
    e = sub.add_parser("export", help="write a project's poses, kinematics, .tra, .jts or figure")
    e.add_argument("project", metavar="PROJECT.fluoro")
    e.add_argument("--poses", metavar="OUT.csv", help="both poses (6 numbers and the 4x4), residuals, status, SDs "
                                                      "and kinematics, one row per frame")
    e.add_argument("--kinematics", metavar="OUT.csv", help="knee kinematics, one row per frame")
    e.add_argument("--tra", metavar="OUT.tra", help="Autoscoper: femoral then tibial 4x4, row by row, per frame")
    e.add_argument("--jts", metavar="DIR", help="JointTrack femoral.jts and tibial.jts (needs --view)")
    e.add_argument("--view", type=int, metavar="K", help="the view (1 = first) whose camera frame --jts uses")
    e.add_argument("--include-unreviewed", action="store_true",
                   help="--tra/--jts: also write poses the matcher flagged for review (those files carry no status; "
                        "by default such poses are left out as NaN)")
    e.add_argument("--plot", metavar="OUT.png|svg|pdf", help="the kinematics figure")
    e.add_argument("--against", choices=("frame", "flexion"), default="frame", help="x axis of --plot")
    e.add_argument("--side", choices=("right", "left"), help="the knee's side, if the project does not say")
    e.set_defaults(func=run_export)

    k = sub.add_parser("kinematics", help="knee kinematics (Grood & Suntay) of poses from anywhere")
    k.add_argument("--poses", required=True, metavar="POSES.csv",
                   help="columns frame,component,x,y,z,alpha,beta,gamma (component femoral or tibial)")
    k.add_argument("--side", required=True, choices=("right", "left"))
    k.add_argument("--femoral-frame", metavar="F.json", help='{"matrix": [[4 rows of 4]]}, anatomical -> model')
    k.add_argument("--tibial-frame", metavar="T.json")
    k.add_argument("--femoral-mesh", metavar="MESH", help="for the default femoral frame")
    k.add_argument("--tibial-mesh", metavar="MESH", help="for the default tibial frame")
    k.add_argument("--out", required=True, metavar="OUT.csv")
    k.set_defaults(func=run_kinematics)


def run_export(args) -> int:
    from fluorogui.io.errors import check_output_file, check_output_folder
    from fluorogui.workflow import exports

    wanted = [args.poses, args.kinematics, args.tra, args.jts, args.plot]
    if not any(wanted):
        raise UsageError("fluorogui: export: say what to write (--poses, --kinematics, --tra, --jts or --plot)")
    if (args.jts is None) != (args.view is None):
        raise UsageError("fluorogui: export: --jts and --view go together")
    if args.plot and Path(args.plot).suffix.lower() not in (".png", ".svg", ".pdf"):
        raise UsageError(f"fluorogui: export: --plot {args.plot}: the figure must be .png, .svg or .pdf")
    for path in (args.poses, args.kinematics, args.tra, args.plot):  # before any work
        if path:
            check_output_file(path)
    if args.jts:
        check_output_folder(args.jts)
    from fluorogui.workflow.session import Session
    from fluorogui.io.errors import InputError

    path = Path(args.project)
    if not path.exists():
        raise InputError(path, "file not found")
    session = Session.open(path)
    if args.view is not None and not 1 <= args.view <= session.n_views:
        raise UsageError(f"fluorogui: export: --view {args.view}: the project has {session.n_views} "
                         f"view{'s' if session.n_views != 1 else ''} (1 = first)")
    if args.side:
        session.set_side(args.side)  # for this export only: the project is not saved
    elif session.side is None and (args.poses or args.kinematics or args.plot):
        warn("the project does not say which knee this is; right assumed (use --side)")
    rows = session.knee_rows() if (args.poses or args.kinematics or args.plot) else []
    written = []
    if args.poses:
        written.append(exports.export_poses_csv(session, args.poses, rows))
    if args.kinematics:
        written.append(exports.export_kinematics_csv(session, args.kinematics, rows))
    if args.tra:
        written.append(exports.export_tra(session, args.tra, args.include_unreviewed))
    if args.jts:
        written += exports.export_jts(session, args.jts, args.view - 1, args.include_unreviewed)
    flagged = exports.unreviewed_matches(session) if (args.tra or args.jts) else []
    if flagged:
        frames = sorted({frame for frame, _, _ in flagged})
        what = ("written although flagged for review" if args.include_unreviewed else
                "flagged for review and left out of --tra/--jts as NaN (accept them in the app, or --include-unreviewed)")
        warn(f"{len(flagged)} pose{'s' if len(flagged) > 1 else ''} {what}: frame{'s' if len(frames) > 1 else ''} "
             f"{_frame_list(frames)}")
    if args.plot:
        written.append(exports.export_plot(session, args.plot, args.against, rows))
    review = [r.frame for r in rows if r.status == "needs_review"]
    missing = [r.frame for r in rows if r.status == "missing"]
    if review:
        warn(f"{len(review)} frame{'s' if len(review) > 1 else ''} need review: {_frame_list(review)}")
    if missing:
        warn(f"{len(missing)} frame{'s' if len(missing) > 1 else ''} lack a pose (NaN): {_frame_list(missing)}")
    for p in written:
        print(f"wrote {p}")
    return 0


def _frame_list(frames: list[int]) -> str:
    text = ", ".join(str(f) for f in frames[:12])
    return text + (f" and {len(frames) - 12} more" if len(frames) > 12 else "")


def load_frame_json(path) -> "object":
    """A frame JSON ``{"matrix": [[4 rows of 4]]}`` (anatomical → model), checked."""
    from fluorogui.core.kinematics import KinematicsError, check_frame
    from fluorogui.io.errors import InputError
    from fluorogui.io.pose_files import read_text_lines

    path = Path(path)
    text = "\n".join(read_text_lines(path))
    try:
        document = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise InputError(path, f"is not JSON ({getattr(exc, 'msg', 'too deeply nested')})") from None
    if not isinstance(document, dict) or "matrix" not in document:
        raise InputError(path, 'must be {"matrix": [[4 rows of 4 numbers]]}')
    try:
        return check_frame(document["matrix"])
    except KinematicsError as exc:
        raise InputError(path, f"'matrix': {exc}") from None


def run_kinematics(args) -> int:
    from fluorogui.core.anatomy import default_frame
    from fluorogui.core.kinematics import KINEMATICS_COLUMNS, SIGN_CONVENTIONS, KinematicsError
    from fluorogui.io.errors import InputError
    from fluorogui.io.meshes import load_mesh
    from fluorogui.io.errors import check_output_file
    from fluorogui.io.pose_files import read_long_poses, write_csv
    from fluorogui.workflow.exports import kinematics_of_poses
    from fluorogui import __version__

    out = check_output_file(args.out)
    frames = {}
    for component, frame_path, mesh_path in (("femoral", args.femoral_frame, args.femoral_mesh),
                                             ("tibial", args.tibial_frame, args.tibial_mesh)):
        if frame_path:
            frames[component] = load_frame_json(frame_path)
        elif mesh_path:
            vertices, faces = load_mesh(mesh_path)
            try:
                frames[component] = default_frame(component, vertices, faces)
            except KinematicsError as exc:
                raise InputError(mesh_path, f"no default anatomical frame: {exc}") from None
        else:
            raise UsageError(f"fluorogui: kinematics: give --{component}-frame or --{component}-mesh "
                             f"(the default {component} frame comes from the mesh)")
    poses = read_long_poses(args.poses)
    rows = kinematics_of_poses(poses, args.side, frames["femoral"], frames["tibial"])
    header = [f"fluorogui {__version__} knee kinematics of {Path(args.poses).name}",
              f"side: {args.side}", "units: mm and degrees", f"kinematics: {SIGN_CONVENTIONS}"]
    for component, matrix in frames.items():
        header.append(f"{component} anatomical frame (anatomical -> model): {json.dumps(matrix.round(9).tolist())}")
    header += [f"frame {frame}: NaN: {reason}" for frame, _, reason in rows if reason]
    write_csv(out, header, ["frame", *KINEMATICS_COLUMNS],
              [[frame, *(float(v) for v in values.values())] for frame, values, _ in rows])
    nan_rows = [frame for frame, _, reason in rows if reason]
    if nan_rows:
        warn(f"{len(nan_rows)} frame{'s' if len(nan_rows) > 1 else ''} written as NaN "
             f"({next(r for _, _, r in rows if r)}{', …' if len(nan_rows) > 1 else ''}): {_frame_list(nan_rows)}")
    print(f"wrote {out} ({len(rows)} frames)", file=sys.stdout)
    return 0
