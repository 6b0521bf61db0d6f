"""``fluorogui track``: track components through the frames of a project, over
``Session.track``.

Holds the project's lock while it runs and saves every frame as it finishes (appended to
the project's journal, with a full atomic save every 50 frames and at the end), so a
killed run loses at most the frame in progress and resumes where it stopped
(frames already matched are kept unless ``--redo``). With ``--json`` stdout gets one JSON
object per frame and component as it finishes; frames that need review or failed are
also reported on stderr, one line each. Exit status: 0 when every frame matched, 3 when
some need review or failed, 2 for bad input."""
from __future__ import annotations

import time

from fluorogui.cli.common import (
    COMPONENT_CHOICES,
    UsageError,
    add_quality_option,
    components_arg,
    emit_json,
    int_in,
    locked_session,
    parse_frames,
    progress_bar,
    quality_thresholds,
    report_flagged,
)
from fluorogui.core.status import Status


def add_parser(sub):
    t = sub.add_parser("track", help="track components through frames, flagging what fails its checks")
    t.add_argument("project", metavar="PROJECT")
    t.add_argument("--frames", metavar="A:B", help="frames to track, both ends included (default: all)")
    t.add_argument("--component", choices=COMPONENT_CHOICES, default="both")
    t.add_argument("--redo", action="store_true", help="match again frames already matched (accepted ones are kept)")
    t.add_argument("--workers", type=int_in(1, 256), default=1,
                   help="track N consecutive runs of frames in parallel processes (each after the first starts "
                        "with find implants); results then arrive out of frame order")
    add_quality_option(t, "the project's; what is given is kept in the project")
    t.add_argument("--json", action="store_true", help="one JSON object per frame and component as it finishes")
    return t


def run(args) -> int:
    with locked_session(args.project, "fluorogui track") as session:
        if not session.components():
            raise UsageError(f"fluorogui: track: {args.project} has no implant models")
        frames = parse_frames(args.frames, session.frames)
        if args.quality:  # the project's thresholds from now on: its statuses are judged by them
            settings = session.settings
            settings.quality = quality_thresholds(args.quality, settings.quality)
            session.set_settings(settings)
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
    return 3 if counts.get(Status.NEEDS_REVIEW) or counts.get(Status.FAILED) else 0
