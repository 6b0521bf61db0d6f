"""Tracking many projects in parallel with Dask distributed.

A study is many trials (knees x activities x frames); ``run_batch`` tracks each project
as one Dask task: on a ``LocalCluster`` using this machine's cores by default, or on an
existing scheduler (``scheduler="tcp://host:8786"``) so the same call runs on a cluster
whose workers see the same files. Each task opens its project under the project lock,
tracks with every frame saved as it finishes (the journal), and returns a summary; a project that
cannot be opened or is in use elsewhere becomes a summary row with the reason, and the
batch goes on.

A worker that dies mid-frame loses only that frame: Dask reschedules the task on
another worker (up to ``distributed.scheduler.allowed-failures`` times), and the retried
task keeps every frame the run already stored (the run id is written into each match
record) and continues from there.
"""
from __future__ import annotations

import logging
import time
import uuid
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Sequence

from fluorogui.core.status import Status


@dataclass
class ProjectSummary:
    """How tracking one project went."""

    project: str
    ok: bool
    frames: int = 0
    matched: int = 0
    needs_review: int = 0
    failed: int = 0
    kept: int = 0
    seconds: float = 0.0
    error: str = ""
    flagged: list = field(default_factory=list)  # [frame, component, status, reason]

    def to_dict(self) -> dict:
        return asdict(self)


def track_project(path: str, *, frames: str | None = None, components="both", redo: bool = False,
                  run: str | None = None, on_frame: Callable | None = None) -> ProjectSummary:
    """Track one project (a Dask task; also callable directly). ``frames`` is a frame spec
    ("A:B"); ``on_frame(path, frame)`` is called after each frame is saved."""
    from fluorogui.io.errors import InputError
    from fluorogui.io.project.lock import ProjectLock
    from fluorogui.workflow.session import Session
    from fluorogui.workflow.tracking import select_frames

    t0 = time.perf_counter()
    summary = ProjectSummary(str(path), ok=False)
    try:
        with ProjectLock(path, "fluorogui batch", token=run):
            session = Session.open(path)
            chosen = select_frames(frames, session.frames)
            summary.frames = len(chosen)
            last = None
            for r in session.track(chosen, components, redo=redo, autosave=True, run=run):
                if r.kept:
                    summary.kept += 1
                elif r.status == Status.MATCHED:
                    summary.matched += 1
                elif r.status == Status.NEEDS_REVIEW:
                    summary.needs_review += 1
                else:
                    summary.failed += 1
                if not r.kept and r.status in (Status.NEEDS_REVIEW, Status.FAILED):
                    summary.flagged.append([r.frame, r.component, r.status, r.reason])
                if on_frame is not None and r.frame != last:
                    on_frame(str(path), r.frame)
                last = r.frame
        summary.ok = True
    except (InputError, KeyError, ValueError) as exc:
        summary.error = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
    summary.seconds = time.perf_counter() - t0
    return summary


def run_batch(paths: Sequence[str], *, workers: int | None = None, scheduler: str | None = None,
              frames: str | None = None,
              components="both", redo: bool = False, on_frame: Callable | None = None,
              threads_per_worker: int = 1) -> Iterator[ProjectSummary]:
    """Track every project in ``paths`` on a Dask cluster; yields summaries as projects finish.

    Without ``scheduler`` a LocalCluster of ``workers`` processes (default: the machine's
    cores) is started and closed again."""
    from distributed import Client, LocalCluster, as_completed

    run = uuid.uuid4().hex[:12]
    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        import os

        n = workers or os.cpu_count() or 1
        cluster = LocalCluster(n_workers=n, threads_per_worker=threads_per_worker, processes=True,
                               dashboard_address=None, silence_logs=logging.CRITICAL)
        client = Client(cluster)
    try:
        futures = {client.submit(track_project, str(Path(p).absolute()), frames=frames, components=components,
                                 redo=redo, run=run, on_frame=on_frame, key=f"track-{run}-{i}", pure=False): p
                   for i, p in enumerate(paths)}
        for future in as_completed(futures):
            try:
                yield future.result()
            except Exception as exc:  # noqa: BLE001 - a lost task is a row of the summary, not a crash
                yield ProjectSummary(str(futures[future]), ok=False, error=f"{type(exc).__name__}: {exc}")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def summary_table(rows: Sequence[ProjectSummary]) -> str:
    """The table printed at the end of a batch."""
    head = f"{'project':<40} {'frames':>6} {'matched':>7} {'review':>6} {'failed':>6} {'kept':>5} {'s':>7}  note"
    lines = [head, "-" * len(head)]
    for r in rows:
        name = r.project if len(r.project) <= 40 else "…" + r.project[-39:]
        note = r.error if not r.ok else ("" if not r.flagged else f"{len(r.flagged)} flagged")
        lines.append(f"{name:<40} {r.frames:>6} {r.matched:>7} {r.needs_review:>6} {r.failed:>6} {r.kept:>5} "
                     f"{r.seconds:>7.1f}  {note}")
    return "\n".join(lines)
