"""What the workflow sub-commands share: frame specs, opening a project under its lock,
per-frame output (JSON lines on stdout, flagged frames on stderr) and a progress bar
that appears only on a terminal."""
from __future__ import annotations

import json
import sys
from contextlib import contextmanager
from pathlib import Path

COMPONENT_CHOICES = ("femoral", "tibial", "both")


class UsageError(Exception):
    """A command-line mistake: one line on stderr, exit 2."""


def parse_frames(spec: str | None, frames: list[int]) -> list[int]:
    """``workflow.tracking.select_frames`` with its mistakes as usage errors."""
    from fluorogui.workflow.tracking import select_frames

    try:
        return select_frames(spec, frames)
    except ValueError as exc:
        raise UsageError(f"fluorogui: --frames {exc}") from None


def components_arg(value: str) -> str | list[str]:
    return "both" if value == "both" else [value]


@contextmanager
def locked_session(path, program: str):
    """Open a project under its lock; the lock is released on the way out."""
    from fluorogui.io.errors import InputError
    from fluorogui.io.lock import ProjectLock
    from fluorogui.workflow.session import Session

    path = Path(path)
    if not path.exists():
        raise InputError(path, "file not found")
    with ProjectLock(path, program):
        yield Session.open(path)


def emit_json(obj: dict) -> None:
    print(json.dumps(obj), flush=True)


def warn(text: str) -> None:
    print(f"fluorogui: {text}", file=sys.stderr, flush=True)


def progress_bar(total: int, label: str):
    """A tqdm bar on stderr when it is a terminal, else None."""
    if not sys.stderr.isatty() or total <= 1:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=label, unit="frame", file=sys.stderr, dynamic_ncols=True, leave=False)


def report_flagged(result) -> None:
    """A frame that needs review or failed: one line on stderr."""
    if result.kept or result.status in ("matched", "placed"):
        return
    word = "needs review" if result.status == "needs_review" else "failed"
    warn(f"frame {result.frame}, {result.component}: {word}: {result.reason}")
