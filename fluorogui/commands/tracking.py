"""``fluorogui find`` and ``fluorogui track``: the session's find and track over a project.

Both hold the project's lock while they run and write the project atomically after
every frame, so a killed run loses at most the frame in progress and ``track`` resumes
where it stopped (frames already matched are kept unless ``--redo``). With ``--json``
stdout gets one JSON object per frame and component as it finishes; frames that need
review or failed are also reported on stderr, one line each. Exit status: 0 when every
frame matched, 3 when some need review or failed, 2 for bad input.
"""
from __future__ import annotations

import time

from fluorogui.commands.common import (
    COMPONENT_CHOICES,
    components_arg,
    emit_json,
    int_in,
    locked_session,
    parse_frames,
    progress_bar,
    report_flagged,
    warn,
)


def add_parsers(sub) -> None:
    f = sub.add_parser("find", help="find the implants in frames (no start pose needed)")
    f.add_argument("project", metavar="PROJECT")
    f.add_argument("--frames", required=True, metavar="SPEC", help="A:B (both included), N, or a list: 0,20:40")
    f.add_argument("--component", choices=COMPONENT_CHOICES, default="both")
    f.add_argument("--json", action="store_true", help="one JSON object per frame and component")
    f.set_defaults(func=run_find)

    t = sub.add_parser("track", help="track components through frames, flagging what fails its checks")
    t.add_argument("project", metavar="PROJECT")
    t.add_argument("--frames", metavar="A:B", help="frames to track, both ends included (default: all)")
    t.add_argument("--component", choices=COMPONENT_CHOICES, default="both")
    t.add_argument("--redo", action="store_true", help="match again frames already matched (accepted ones are kept)")
    t.add_argument("--workers", type=int_in(1, 256), default=1,
                   help="track N consecutive runs of frames in parallel processes (each after the first starts "
                        "with find implants); results then arrive out of frame order")
    t.add_argument("--json", action="store_true", help="one JSON object per frame and component as it finishes")
    t.set_defaults(func=run_track)


def run_find(args) -> int:
    with locked_session(args.project, "fluorogui find") as session:
        frames = parse_frames(args.frames, session.frames)
        components = components_arg(args.component)
        bar = progress_bar(len(frames), "find")
        flagged = 0
        for frame in frames:
            t0 = time.perf_counter()
            placements = session.find(frame, components)
            session.save()
            for p in placements.values():
                if args.json:
                    emit_json({"frame": frame, "component": p.component, "found": p.found,
                               "pose": None if p.pose is None else [round(float(v), 6) for v in p.pose],
                               "iou": [round(float(v), 4) for v in p.iou], "reason": p.reason,
                               "seconds": round(p.seconds, 3)})
                elif bar is None:
                    print(f"frame {frame}: {p.describe()}")
                if not p.found:
                    flagged += 1
                    warn(f"frame {frame}, {p.component}: not placed: {p.reason}")
            if bar is not None:
                bar.update(1)
                bar.set_postfix_str(f"frame {frame} {time.perf_counter() - t0:.1f} s")
        if bar is not None:
            bar.close()
    return 3 if flagged else 0


def run_track(args) -> int:
    from fluorogui.commands.common import UsageError

    with locked_session(args.project, "fluorogui track") as session:
        if not session.components():
            raise UsageError(f"fluorogui: track: {args.project} has no implant models")
        frames = parse_frames(args.frames, session.frames)
        bar = progress_bar(len(frames), "track")
        counts: dict[str, int] = {}
        t0 = time.perf_counter()
        last_frame = None

        if args.workers < 1:
            raise UsageError("fluorogui: track: --workers must be at least 1")
        for result in session.track(frames, components_arg(args.component), redo=args.redo, autosave=True,
                                    workers=args.workers):
            status = "kept" if result.kept else result.status
            counts[status] = counts.get(status, 0) + 1
            if args.json:
                emit_json(result.to_json())
            report_flagged(result)
            if bar is not None and result.frame != last_frame:
                bar.update(1)
                bar.set_postfix_str(f"frame {result.frame}")
            last_frame = result.frame
        if bar is not None:
            bar.close()
        seconds = time.perf_counter() - t0
    summary = ", ".join(f"{n} {k.replace('_', ' ')}" for k, n in sorted(counts.items()))
    if not args.json:
        print(f"tracked {len(frames)} frames in {seconds:.1f} s: {summary or 'nothing to do'}")
    return 3 if counts.get("needs_review") or counts.get("failed") else 0


def add_batch_parser(sub) -> None:
    b = sub.add_parser("batch", help="track many projects in parallel (Dask distributed)")
    b.add_argument("projects", nargs="+", metavar="PROJECT")
    b.add_argument("--workers", type=int_in(1, 1024), help="local worker processes (default: the machine's cores)")
    b.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://host:8786")
    b.add_argument("--frames", metavar="A:B", help="frames to track in every project (default: all)")
    b.add_argument("--component", choices=COMPONENT_CHOICES, default="both")
    b.add_argument("--redo", action="store_true", help="match again frames already matched")
    b.add_argument("--json", action="store_true", help="one JSON summary per project as it finishes")
    b.set_defaults(func=run_batch_command)


def run_batch_command(args) -> int:
    from fluorogui.commands.common import UsageError
    from fluorogui.workflow.batch import run_batch, summary_table

    if args.workers is not None and args.workers < 1:
        raise UsageError("fluorogui: batch: --workers must be at least 1")
    if args.workers and args.scheduler:
        raise UsageError("fluorogui: batch: give --workers or --scheduler, not both")
    rows = []
    bar = progress_bar(len(args.projects), "batch")
    for row in run_batch(args.projects, args.workers, args.scheduler, args.frames, components_arg(args.component),
                         args.redo):
        rows.append(row)
        if args.json:
            emit_json(row.to_dict())
        if not row.ok:
            warn(row.error if row.error.startswith(row.project) else f"{row.project}: {row.error}")
        for frame, component, status, reason in row.flagged:
            warn(f"{row.project}: frame {frame}, {component}: {status.replace('_', ' ')}: {reason}")
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    if not args.json:
        print(summary_table(rows))
    if any(not r.ok for r in rows):
        return 2
    return 3 if any(r.needs_review or r.failed for r in rows) else 0
