"""``fluorogui export``: a project's results in every format of the export registry
(``fluorogui.workflow.exports``: poses, kinematics, .tra, .jts, the figure, C3D, OpenSim
.mot / .trc, XMALab rigid-body CSV), one option per format, made from the registry.
``--fps`` overrides the project's frame rate for this export; the files that need time
refuse, in one line, when there is none."""
from __future__ import annotations

import argparse
from pathlib import Path

from fluorogui.cli.common import UsageError, warn


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
    from fluorogui.workflow.exports.registry import formats

    e = sub.add_parser("export", help="write a project's poses, kinematics, .tra, .jts or figure")
    e.add_argument("project", metavar="PROJECT.fluoro")
    for fmt in formats():  # one option per registered format
        e.add_argument(f"--{fmt.name}", metavar=fmt.metavar, help=fmt.help)
    for fmt in formats():  # and the formats' own options
        for option in fmt.options:
            e.add_argument(option.flag, dest=option.dest, metavar=option.metavar or None, default=option.default,
                           type=_argparse_type(option), help=f"--{fmt.name}: {option.help}")
    e.add_argument("--view", type=int, metavar="K", help="the view (1 = first) whose camera frame "
                                                         f"{_options(f for f in formats() if f.needs_view)} uses")
    e.add_argument("--fps", type=fps_value, metavar="N", help="frame rate for this export (time = frame / N), "
                                                             "instead of the project's")
    statusless = _options(f for f in formats() if f.statusless)
    motion = _options(f for f in formats() if f.motion)
    e.add_argument("--include-unreviewed", action="store_true",
                   help=f"{statusless}: also write poses the matcher flagged for review (those files carry no "
                        f"status; by default such poses are left out as NaN); {motion}: also poses placed "
                        "by hand or flagged and not accepted (by default invalid markers, NaN values)")
    e.add_argument("--against", choices=("frame", "flexion"), default="frame", help="x axis of --plot")
    e.add_argument("--side", choices=("right", "left"), help="the knee's side, if the project does not say")
    return e


def _argparse_type(option):
    """``option.parse`` as an argparse type: its ValueError is argparse's one-line usage error."""
    def parse(text):
        try:
            return option.parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = option.metavar or option.dest
    return parse


def _options(chosen, joint: str = "/") -> str:
    return joint.join(f"--{f.name}" for f in chosen)


def run(args) -> int:
    from fluorogui.io.errors import InputError
    from fluorogui.workflow.exports import ExportOptions, export_notes, formats, frame_rate, write_exports
    from fluorogui.workflow.session import Session

    chosen = [f for f in formats() if getattr(args, f.name, None)]
    if not chosen:
        every = [f"--{f.name}" for f in formats()]
        raise UsageError(f"fluorogui: export: say what to write ({', '.join(every[:-1])} or {every[-1]})")
    for fmt in formats():  # a format's options without the format: a mistake
        stray = [o.flag for o in fmt.options if fmt not in chosen and getattr(args, o.dest) != o.default]
        if stray:
            raise UsageError(f"fluorogui: export: {stray[0]} goes with --{fmt.name}")
    with_view = [f for f in formats() if f.needs_view]
    if any(f in chosen for f in with_view) != (args.view is not None):
        raise UsageError(f"fluorogui: export: {_options(with_view)} and --view go together")
    for fmt in chosen:  # before any work
        if problem := fmt.wrong_suffix(getattr(args, fmt.name)):
            raise UsageError(f"fluorogui: export: --{fmt.name} {getattr(args, fmt.name)}: {problem}")
    for fmt in chosen:
        fmt.check_target(getattr(args, fmt.name))
    path = Path(args.project)
    if not path.exists():
        raise InputError(path, "file not found")
    session = Session.open(path)
    if args.view is not None and not 1 <= args.view <= session.n_views:
        raise UsageError(f"fluorogui: export: --view {args.view}: the project has {session.n_views} "
                         f"view{'s' if session.n_views != 1 else ''} (1 = first)")
    timed = [f"--{f.name}" for f in chosen if f.timed]
    if timed and args.fps is None and frame_rate(session) is None:
        raise UsageError(f"fluorogui: export: {' and '.join(timed)} need{'s' if len(timed) == 1 else ''} a frame rate "
                         f"(time = frame / fps) and {path.name} has none; give --fps N "
                         "(or import with --fps N)")
    kinematic = any(f.kinematic for f in chosen)
    if args.side:
        session.set_side(args.side)  # for this export only: the project is not saved
    elif session.side is None and kinematic:
        warn("the project does not say which knee this is; right assumed (use --side)")
    rows = session.knee_rows() if kinematic else []
    extra = {o.dest: getattr(args, o.dest) for fmt in chosen for o in fmt.options}
    options = ExportOptions(fps=args.fps, include_unreviewed=args.include_unreviewed,
                            view=None if args.view is None else args.view - 1, against=args.against, rows=rows,
                            extra=extra)
    written = write_exports(session, {f.name: getattr(args, f.name) for f in chosen}, options)
    for poses, words in export_notes(session, [f.name for f in chosen], options, naming=lambda f: f"--{f.name}",
                                     remedy="accept them in the app, or --include-unreviewed"):
        if poses:
            _warn_poses(poses, words)
        else:
            warn(words)
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
