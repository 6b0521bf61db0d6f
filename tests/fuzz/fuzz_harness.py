"""Saves under attack: a child process saving a file is killed at a random moment, or
saves with a file-size limit (``RLIMIT_FSIZE``, a full disk in miniature). Shared by
the quick tests in this folder and the long run ``python tools/fuzz.py``.

Every version a child writes is a JSON document ``{"version": n, "pad": "...", "sum": s}``
whose ``sum`` checks its ``pad``: a file that parses and checks is whole."""
from __future__ import annotations

import json
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

_SAVER = r"""
import json, os, signal, sys, resource
sys.path.insert(0, {repo!r})
from fluorogui.io.errors import InputError
from fluorogui.io.files import atomic_write_text
path, first, limit = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
if limit:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of death, like a full disk
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
n = first
while True:
    pad = (str(n) * 400_000)[: 400_000 + (n % 7) * 50_000]
    text = json.dumps({{"version": n, "pad": pad, "sum": sum(map(ord, pad))}})
    try:
        atomic_write_text(path, text, backup=True)
    except InputError as exc:
        print(exc, flush=True)
        sys.exit(2)
    print(n, flush=True)
    if limit:
        sys.exit(0)
    n += 1
"""


def whole_version(path: Path) -> int | None:
    """The version of a whole document at ``path``; None if missing, truncated or corrupt."""
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
        if sum(map(ord, document["pad"])) == document["sum"]:
            return int(document["version"])
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return None


def _saver(path: Path, first: int, limit: int = 0) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", _SAVER.format(repo=str(REPO)), str(path), str(first), str(limit)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def leftover_temps(folder: Path, name: str) -> list[Path]:
    return [p for p in folder.iterdir() if p.name.startswith(f".{name}.") and p.name.endswith(".tmp")]


def kill_trials(folder: Path, trials: int, seed: int = 0) -> dict:
    """Kill a saving child ``trials`` times at random moments; count what was lost.

    After each kill the project and its backup must both be whole (the backup at most one
    version behind), and the next save must leave no temp file behind."""
    from fluorogui.io.files import atomic_write_text, clean_stale_temps

    rng = random.Random(seed)
    path = folder / "killed.fluoro"
    counts = {"trials": 0, "lost_or_truncated_project": 0, "lost_or_truncated_backup": 0,
              "leftover_temps_after_next_save": 0, "temps_left_by_kills": 0}
    previous, version = 1, 2
    for v in (previous, version):  # a project with a backup to begin with
        atomic_write_text(path, json.dumps({"version": v, "pad": "", "sum": 0}), backup=True)
    for _ in range(trials):
        child = _saver(path, version + 1)
        child.stdout.readline() if rng.random() < 0.5 else None  # sometimes after a first save
        time.sleep(rng.uniform(0.0, 0.25))
        child.send_signal(signal.SIGKILL)
        child.communicate()
        counts["trials"] += 1
        current, backup = whole_version(path), whole_version(path.with_name(path.name + ".bak"))
        if current is None:
            counts["lost_or_truncated_project"] += 1
        # the backup is the version before the current one (the child's previous save, or
        # ours), or the current one itself when the kill fell between the two renames
        expected_backup = previous if current == version else (current or 0) - 1
        if backup is None or backup not in (expected_backup, current):
            counts["lost_or_truncated_backup"] += 1
        counts["temps_left_by_kills"] += len(leftover_temps(folder, path.name))
        previous, version = current, max(version, current or 0) + 10_000
        clean_stale_temps(path)
        atomic_write_text(path, json.dumps({"version": version, "pad": "", "sum": 0}), backup=True)
        counts["leftover_temps_after_next_save"] += len(leftover_temps(folder, path.name))
    return counts


def full_disk_trials(folder: Path, limits) -> dict:
    """Save with each file-size limit in ``limits`` (bytes); the save must fail with one line
    naming the file, and leave the project, its backup and no temp files behind."""
    from fluorogui.io.files import atomic_write_text

    path = folder / "full.fluoro"
    counts = {"trials": 0, "lost_or_truncated_project": 0, "lost_or_truncated_backup": 0,
              "leftover_temps": 0, "unclear_messages": 0, "accepted": 0}
    for limit in limits:
        atomic_write_text(path, json.dumps({"version": 1, "pad": "", "sum": 0}), backup=True)
        atomic_write_text(path, json.dumps({"version": 2, "pad": "", "sum": 0}), backup=True)
        child = _saver(path, 3, limit)
        out, _ = child.communicate(timeout=60)
        counts["trials"] += 1
        if child.returncode == 0:
            counts["accepted"] += 1
        elif child.returncode != 2 or not out.startswith(f"{path}: could not save:") or out.count("\n") != 1:
            counts["unclear_messages"] += 1
        if whole_version(path) != (3 if child.returncode == 0 else 2):
            counts["lost_or_truncated_project"] += 1
        if whole_version(path.with_name(path.name + ".bak")) != (2 if child.returncode == 0 else 1):
            counts["lost_or_truncated_backup"] += 1
        counts["leftover_temps"] += len(leftover_temps(folder, path.name))
    return counts
