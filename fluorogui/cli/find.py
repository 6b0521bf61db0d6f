"""``fluorogui find``: *find implants* in frames of a project (no start pose needed), over
``Session.find``. Holds the project's lock and saves after every frame. Exit status: 0
when every component was placed, 3 when some were not, 2 for bad input."""
from __future__ import annotations

import time

from fluorogui.cli.common import (
    COMPONENT_CHOICES,
    components_arg,
    emit_json,
    locked_session,
    parse_frames,
    progress_bar,
    warn,
)


def add_parser(sub):
    f = sub.add_parser("find", help="find the implants in frames (no start pose needed)")
    f.add_argument("project", metavar="PROJECT")
    f.add_argument("--frames", required=True, metavar="SPEC", help="A:B (both included), N, or a list: 0,20:40")
    f.add_argument("--component", choices=COMPONENT_CHOICES, default="both")
    f.add_argument("--json", action="store_true", help="one JSON object per frame and component")
    return f


def run(args) -> int:
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
