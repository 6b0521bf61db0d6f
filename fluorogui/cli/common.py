"""What the sub-commands share: the one usage error and its parser, option types with
ranges and counts, native library chatter sent to the log file, frame specs, opening a project under
its lock, per-frame output (JSON lines on stdout, flagged frames on stderr) and a progress
bar that appears only on a terminal. The inputs they load are in ``cli.inputs``."""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from contextlib import contextmanager
from pathlib import Path

from fluorogui.core.status import Status

COMPONENT_CHOICES = ("femoral", "tibial", "both")

# ranges of the numeric options (the matcher checks what a method needs beyond them)
STARTS_RANGE = (1, 1000)
POINTS_RANGE = (10, 5_000_000)
OUTLINE_POINTS_RANGE = (1, 100_000)
SEED_RANGE = (0, 2**32 - 1)


class UsageError(Exception):
    """A command-line mistake: one line on stderr, exit 2."""


class Numbers(argparse.Action):
    """An option taking exactly as many values as its ``metavar`` names (a pose: X Y Z ALPHA
    BETA GAMMA). Given more or fewer, the message says how many it takes, where a fixed
    ``nargs`` would leave the rest to argparse's "unrecognized arguments: 1"."""

    def __init__(self, option_strings, dest, metavar, **kwargs):
        super().__init__(option_strings, dest, nargs="+", metavar=tuple(metavar), **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        if len(values) != len(self.metavar):
            raise argparse.ArgumentError(self, f"takes exactly {len(self.metavar)} numbers "
                                               f"({' '.join(self.metavar)}), got {len(values)}")
        setattr(namespace, self.dest, values)


class _Formatter(argparse.HelpFormatter):
    def _format_args(self, action, default_metavar):
        if isinstance(action, Numbers):  # its names, once: "X Y Z ALPHA BETA GAMMA"
            return " ".join(action.metavar)
        return super()._format_args(action, default_metavar)


class Parser(argparse.ArgumentParser):
    """An argument parser whose mistakes are one ``UsageError`` line, not usage + message."""

    def __init__(self, *args, formatter_class=_Formatter, **kwargs):
        super().__init__(*args, formatter_class=formatter_class, **kwargs)

    def error(self, message):
        raise UsageError(f"{self.prog}: {message}")


# -- option types ---------------------------------------------------------------------------------


def int_in(least: int, most: int):
    """An argparse type: a whole number from ``least`` to ``most``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text[:30]!r} is not a whole number") from None
        if not least <= value <= most:
            raise argparse.ArgumentTypeError(f"{value} is out of range; give {least} to {most}")
        return value

    parse.__name__ = "whole number"
    return parse


def finite_float(text: str) -> float:
    """An argparse type: a finite number (nan and inf refused)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text[:30]!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text[:30]!r} is NaN or infinite; give a finite number")
    if abs(value) > 1e7:
        raise argparse.ArgumentTypeError(f"{text[:30]!r} is too large (at most 1e7 in size)")
    return value


finite_float.__name__ = "number"


# -- terminal -----------------------------------------------------------------------------------


@contextmanager


def native_stderr_to_log(log_path):
    """Send what C libraries (VTK, libpng, libtiff) write to the process's stderr into the log
    file at ``log_path`` while the block runs; Python's own ``sys.stderr`` keeps the terminal.
    With ``log_path`` None (``--verbose``, or no log file) nothing changes."""
    if log_path is None or os.name != "posix":
        yield
        return
    try:
        sys.stderr.flush()
        Path(log_path).parent.mkdir(parents=True, exist_ok=True)
        log_fd = os.open(log_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        saved_fd = os.dup(2)
    except OSError:
        yield
        return
    python_stderr = sys.stderr
    on_fd2 = _fileno(python_stderr) == 2
    if on_fd2:  # keep Python's messages on the terminal through a copy of the old fd 2
        sys.stderr = os.fdopen(os.dup(saved_fd), "w", buffering=1, encoding=python_stderr.encoding,
                               errors="backslashreplace")
    os.dup2(log_fd, 2)
    os.close(log_fd)
    try:
        yield
    finally:
        if on_fd2:
            sys.stderr.flush()
            sys.stderr.close()
            sys.stderr = python_stderr
        os.dup2(saved_fd, 2)
        os.close(saved_fd)


def _fileno(stream) -> int | None:
    try:
        return stream.fileno()
    except (AttributeError, OSError, ValueError):
        return None


def add_rim_options(parser, what: str = "match") -> None:
    """``--rim`` / ``--no-rim`` (dest ``rim``: "on", "off", default "auto"), as the automatic
    outline loop's ``LoopSettings.rim``."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--rim", dest="rim", action="store_const", const="on", default="auto",
                       help="automatic outlines: always move them to the boundary the metal's rim profile gives "
                            f"(core.outlines.rim; default for this {what}: only in views whose edge is soft)")
    group.add_argument("--no-rim", dest="rim", action="store_const", const="off",
                       help="automatic outlines: never refine them for the metal's rim (Canny's edges as found)")


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
    from fluorogui.io.project.lock import ProjectLock
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
    if result.kept or result.status in (Status.MATCHED, Status.PLACED):
        return
    word = "needs review" if result.status == Status.NEEDS_REVIEW else "failed"
    warn(f"frame {result.frame}, {result.component}: {word}: {result.reason}")


def add_match_options(p) -> None:
    """``--points``, ``--outline-points``, ``--method`` and ``--starts`` of a match."""
    p.add_argument("--points", type=int_in(*POINTS_RANGE), default=15000, help="point-model size (paper method)")
    p.add_argument("--outline-points", type=int_in(*OUTLINE_POINTS_RANGE), default=None,
                   help="outline points per view (paper default 60)")
    p.add_argument("--method", choices=["fast", "paper"], default="fast")
    p.add_argument("--starts", type=int_in(*STARTS_RANGE), default=1, help="independent starts; the best match is kept")


def add_quality_option(p, what: str) -> None:
    """``--quality NAME=VALUE`` (repeatable): a quality threshold (``QualityThresholds``) to
    judge by; ``what`` says where the others come from."""
    p.add_argument("--quality", action="append", metavar="NAME=VALUE", default=[],
                   help=f"judge with this quality threshold, e.g. max_sd_mm=0.5 (repeatable; the others: {what}); "
                        "names: see docs/methods/quality")


def quality_thresholds(pairs, base):
    """``base`` (a ``QualityThresholds``) with the ``--quality NAME=VALUE`` pairs set; a
    usage error names an unknown threshold or a value out of range."""
    from dataclasses import fields, replace

    names = [f.name for f in fields(base)]
    changes = {}
    for pair in pairs or []:
        name, sep, text = pair.partition("=")
        name = name.strip()
        if not sep or name not in names:
            raise UsageError(f"fluorogui: --quality {pair!r}: give NAME=VALUE, NAME one of {', '.join(names)}")
        try:
            changes[name] = finite_float(text.strip())
        except argparse.ArgumentTypeError as exc:
            raise UsageError(f"fluorogui: --quality {name}: {exc}") from None
    try:
        return replace(base, **changes)
    except ValueError as exc:
        raise UsageError(f"fluorogui: --quality: {exc}") from None
