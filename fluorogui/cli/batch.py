"""``fluorogui batch``: track many projects in parallel (Dask distributed), over
``workflow.batch.run_batch``. Exit status: 0 when every frame of every project matched,
3 when some need review or failed, 2 when a project could not be tracked."""
from __future__ import annotations

from fluorogui.cli.common import COMPONENT_CHOICES, UsageError, components_arg, emit_json, int_in, progress_bar, warn


def add_parser(sub):
    b = sub.add_parser("batch", help="track many projects in parallel (Dask distributed)")
    b.add_argument("projects", nargs="+", metavar="PROJECT")
    b.add_argument("--workers", type=int_in(1, 1024), help="local worker processes (default: the machine's cores)")
    b.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://host:8786")
    b.add_argument("--frames", metavar="A:B", help="frames to track in every project (default: all)")
    b.add_argument("--component", choices=COMPONENT_CHOICES, default="both")
    b.add_argument("--redo", action="store_true", help="match again frames already matched")
    b.add_argument("--json", action="store_true", help="one JSON summary per project as it finishes")
    return b


def run(args) -> int:
    from fluorogui.workflow.batch import run_batch, summary_table

    if args.workers is not None and args.workers < 1:
        raise UsageError("fluorogui: batch: --workers must be at least 1")
    if args.workers and args.scheduler:
        raise UsageError("fluorogui: batch: give --workers or --scheduler, not both")
    rows = []
    bar = progress_bar(len(args.projects), "batch")
    for row in run_batch(args.projects, workers=args.workers, scheduler=args.scheduler, frames=args.frames,
                         components=components_arg(args.component),
                         redo=args.redo):
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
