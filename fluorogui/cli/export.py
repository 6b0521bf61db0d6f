"""``fluorogui export``: a project's poses, kinematics, .tra, .jts or figure, and for the
analysis that continues elsewhere C3D, OpenSim .mot / .trc and XMALab rigid-body CSV, over
``fluorogui.workflow.exports``. ``--fps`` overrides the project's frame rate for this
export; the files that need time refuse, in one line, when there is none."""
from __future__ import annotations

import argparse
from pathlib import Path

from fluorogui.cli.common import UsageError, warn

TIMED = ("c3d", "trc", "mot")  # the exports that need a frame rate


def fps_value(text: str) -> float:
    """An argparse type: a frame rate above 0 (frames per second)."""
    from fluorogui.io.errors import InputError
    from fluorogui.io.motion_files import check_fps

    try:
        return check_fps(text, "--fps")
    except InputError as exc:
        raise argparse.ArgumentTypeError(exc.problem) from None


fps_value.__name__ = "frame rate"


def add_parser(sub):
    e = sub.add_parser("export", help="write a project's poses, kinematics, .tra, .jts or figure")
    e.add_argument("project", metavar="PROJECT.fluoro")
    e.add_argument("--poses", metavar="OUT.csv", help="both poses (6 numbers and the 4x4), residuals, status, SDs "
                                                      "and kinematics, one row per frame")
    e.add_argument("--kinematics", metavar="OUT.csv", help="knee kinematics, one row per frame")
    e.add_argument("--tra", metavar="OUT.tra", help="Autoscoper: femoral then tibial 4x4, row by row, per frame")
    e.add_argument("--jts", metavar="DIR", help="JointTrack femoral.jts and tibial.jts (needs --view)")
    e.add_argument("--view", type=int, metavar="K", help="the view (1 = first) whose camera frame --jts uses")
    e.add_argument("--c3d", metavar="OUT.c3d", help="C3D: per component the anatomical origin and the points 10 mm "
                                                    "along its x, y, z axes (world mm), one C3D frame per frame")
    e.add_argument("--mot", metavar="OUT.mot", help="OpenSim motion: time and the six knee values (degrees, metres)")
    e.add_argument("--trc", metavar="OUT.trc", help="OpenSim markers: the C3D's markers")
    e.add_argument("--xromm", metavar="OUT.csv", help="XMALab rigid-body transformations: per component 16 numbers "
                                                      "(the 4x4, column by column) per frame")
    e.add_argument("--fps", type=fps_value, metavar="N", help="frame rate for this export (time = frame / N), "
                                                             "instead of the project's")
    e.add_argument("--include-unreviewed", action="store_true",
                   help="--tra/--jts: also write poses the matcher flagged for review (those files carry no status; "
                        "by default such poses are left out as NaN); --c3d/--trc/--mot/--xromm: also poses placed "
                        "by hand or flagged and not accepted (by default invalid markers, NaN values)")
    e.add_argument("--plot", metavar="OUT.png|svg|pdf", help="the kinematics figure")
    e.add_argument("--against", choices=("frame", "flexion"), default="frame", help="x axis of --plot")
    e.add_argument("--side", choices=("right", "left"), help="the knee's side, if the project does not say")
    return e


def run(args) -> int:
    from fluorogui.io.files import check_output_file, check_output_folder
    from fluorogui.workflow import exports

    motion = [args.c3d, args.trc, args.mot, args.xromm]
    wanted = [args.poses, args.kinematics, args.tra, args.jts, args.plot, *motion]
    if not any(wanted):
        raise UsageError("fluorogui: export: say what to write (--poses, --kinematics, --tra, --jts, --plot, --c3d, "
                         "--mot, --trc or --xromm)")
    if (args.jts is None) != (args.view is None):
        raise UsageError("fluorogui: export: --jts and --view go together")
    if args.plot and Path(args.plot).suffix.lower() not in (".png", ".svg", ".pdf"):
        raise UsageError(f"fluorogui: export: --plot {args.plot}: the figure must be .png, .svg or .pdf")
    for path in (args.poses, args.kinematics, args.tra, args.plot, *motion):  # before any work
        if path:
            check_output_file(path)
    if args.jts:
        check_output_folder(args.jts)
    from fluorogui.io.errors import InputError
    from fluorogui.workflow.session import Session

    path = Path(args.project)
    if not path.exists():
        raise InputError(path, "file not found")
    session = Session.open(path)
    if args.view is not None and not 1 <= args.view <= session.n_views:
        raise UsageError(f"fluorogui: export: --view {args.view}: the project has {session.n_views} "
                         f"view{'s' if session.n_views != 1 else ''} (1 = first)")
    timed = [f"--{name}" for name in TIMED if getattr(args, name)]
    if timed and args.fps is None and exports.frame_rate(session) is None:
        raise UsageError(f"fluorogui: export: {' and '.join(timed)} need{'s' if len(timed) == 1 else ''} a frame rate "
                         f"(time = frame / fps) and {path.name} has none; give --fps N "
                         "(or import with --fps N)")
    kinematic = args.poses or args.kinematics or args.plot or args.mot
    if args.side:
        session.set_side(args.side)  # for this export only: the project is not saved
    elif session.side is None and kinematic:
        warn("the project does not say which knee this is; right assumed (use --side)")
    rows = session.knee_rows() if kinematic else []
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
        what = ("written although flagged for review" if args.include_unreviewed else
                "flagged for review and left out of --tra/--jts as NaN "
                "(accept them in the app, or --include-unreviewed)")
        _warn_poses(flagged, what)
    if args.c3d:
        written.append(exports.export_c3d(session, args.c3d, args.fps, args.include_unreviewed))
    if args.trc:
        written.append(exports.export_trc(session, args.trc, args.fps, args.include_unreviewed))
    if args.mot:
        written.append(exports.export_mot(session, args.mot, rows, args.fps, args.include_unreviewed))
    if args.xromm:
        written.append(exports.export_xromm(session, args.xromm, args.include_unreviewed))
    left_out = exports.left_out_of_motion_files(session) if any(motion) else []
    if left_out:
        what = ("written although not matched or accepted" if args.include_unreviewed else
                "placed by hand or flagged for review and not accepted, left out of --c3d/--trc/--mot/--xromm "
                "(invalid markers, NaN values; accept them in the app, or --include-unreviewed)")
        _warn_poses(left_out, what)
    if args.c3d and not exports.consecutive_frames(session):
        warn("the project's frame numbers are not consecutive: a C3D reader times C3D frames one 1/fps apart, so "
             "its times are not frame / fps; the C3D's FLUOROGUI:FRAMES and FLUOROGUI:TIMES hold the true ones "
             "(.trc and .mot carry them too)")
    if args.plot:
        written.append(exports.export_plot(session, args.plot, args.against, rows))
    review = [r.frame for r in rows if r.status == "needs_review"]
    missing = [r.frame for r in rows if r.status == "missing"]
    if review:
        warn(f"{len(review)} frame{'s' if len(review) > 1 else ''} need review: {frame_list(review)}")
    if missing:
        warn(f"{len(missing)} frame{'s' if len(missing) > 1 else ''} lack a pose (NaN): {frame_list(missing)}")
    for p in written:
        print(f"wrote {p}")
    return 0


def _warn_poses(poses, what: str) -> None:
    """One warning line for poses (frame, component, ...) treated as ``what`` says."""
    frames = sorted({pose[0] for pose in poses})
    warn(f"{len(poses)} pose{'s' if len(poses) > 1 else ''} {what}: frame{'s' if len(frames) > 1 else ''} "
         f"{frame_list(frames)}")


def frame_list(frames: list[int]) -> str:
    text = ", ".join(str(f) for f in frames[:12])
    return text + (f" and {len(frames) - 12} more" if len(frames) > 12 else "")
