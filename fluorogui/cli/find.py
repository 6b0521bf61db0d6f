"""``fluorogui find``: *find implants* in frames of a project (no start pose needed), over
``Session.find``. Holds the project's lock and saves after every frame. A component
matched or accepted in a frame keeps its pose (said on stderr; ``"kept": true`` in its
JSON object) unless ``--replace``. Exit status: 0 when every component searched for was
placed, 3 when some were not, 2 for bad input."""
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
    f.add_argument("--replace", action="store_true",
                   help="also search for components already matched or accepted in a frame, and replace their poses "
                        "(by default they are kept, and said so on stderr)")
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
            matched = session.matched_in(frame, components)
            placements = session.find(frame, components, replace=args.replace)
            session.save()
            for name in matched:
                if args.replace:
                    if name in placements and placements[name].found:
                        warn(f"frame {frame}, {name}: replaced its matched pose (--replace)")
                    continue
                warn(f"frame {frame}, {name}: kept its matched pose; --replace searches for it again")
                if args.json:
                    pose = session.pose(name, frame)
                    emit_json({"frame": frame, "component": name, "found": False, "kept": True,
                               "pose": [round(float(v), 6) for v in pose], "iou": [],
                               "reason": "kept its matched pose (--replace searches for it again)", "seconds": 0.0})
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
