"""The project's journal: what a long run (tracking) stores frame by frame, appended to a
file beside the project (``<name>.fluoro.journal``) instead of rewriting the whole project
after every frame (a 261-frame project took half a second to save, longer than a frame).

Each line is one JSON object: the records and poses of a frame as the project file holds
them (the same entries), the project's settings when they changed, and the stamp of the
project file it adds to (a hash of its bytes). Opening the project merges the lines whose
stamp is the file's into the document before it is checked, so a journal written over an
older file (saved since by a program that knew no journal) is ignored, and a line cut
short by a kill is dropped: a killed run loses at most the frame in progress. A full save
of the project (atomic) deletes the journal.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from fluorogui.io.errors import InputError, describe_os_error

JOURNAL_SUFFIX = ".journal"
MAX_JOURNAL_BYTES = 1 << 30


def journal_path(project_path) -> Path:
    p = Path(project_path)
    return p.with_name(p.name + JOURNAL_SUFFIX)


def stamp_of(data: bytes) -> str:
    """The stamp of a project file's bytes, which its journal's lines carry."""
    return hashlib.sha256(data).hexdigest()[:32]


def append(project_path, entry: dict) -> None:
    """Append one line (flushed to disk) to the project's journal; InputError naming it."""
    path = journal_path(project_path)
    line = json.dumps(entry, separators=(",", ":"), allow_nan=False) + "\n"
    try:
        with open(path, "a", encoding="utf-8") as handle:
            handle.write(line)
            handle.flush()
            os.fsync(handle.fileno())
    except OSError as exc:
        raise InputError(path, f"could not save: {describe_os_error(exc)}") from None


def discard(project_path) -> None:
    """Delete the journal (after a full save of the project took in what it held)."""
    try:
        journal_path(project_path).unlink()
    except FileNotFoundError:
        pass
    except OSError as exc:
        raise InputError(journal_path(project_path), f"could not delete: {describe_os_error(exc)}") from None


def merge(document: dict, project_path, stamp: str) -> int:
    """Merge the journal's lines written over the file of ``stamp`` into a parsed project
    ``document`` (records and poses replaced by key, settings taken whole); returns how many
    lines were merged. Lines of another file, cut short or not objects are left out."""
    path = journal_path(project_path)
    try:
        if path.stat().st_size > MAX_JOURNAL_BYTES:
            raise InputError(path, f"journal larger than {MAX_JOURNAL_BYTES >> 20} MB; delete it to open the project")
        text = path.read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        return 0
    except OSError as exc:
        raise InputError(path, f"cannot read the journal: {describe_os_error(exc)}") from None
    merged = 0
    records = _by_key(document.get("records"), ("frame", "view", "component"))
    poses = _by_key(document.get("poses"), ("frame", "component"))
    for line in text.splitlines():
        try:
            entry = json.loads(line)
        except ValueError:
            continue  # cut short by a kill
        if not isinstance(entry, dict) or entry.get("stamp") != stamp:
            continue
        for item in entry.get("records") or []:
            if isinstance(item, dict):
                records[tuple(item.get(k) for k in ("frame", "view", "component"))] = item
        for item in entry.get("poses") or []:
            if isinstance(item, dict):
                poses[tuple(item.get(k) for k in ("frame", "component"))] = item
        if isinstance(entry.get("settings"), dict):
            document["settings"] = entry["settings"]
        merged += 1
    if merged:
        document["records"], document["poses"] = list(records.values()), list(poses.values())
    return merged


def _by_key(items, keys) -> dict:
    out = {}
    for item in items if isinstance(items, list) else []:
        key = tuple(item.get(k) for k in keys) if isinstance(item, dict) else (id(item),)
        if key in out:
            key = (id(item),)  # a repeated entry stays repeated, for the checks to refuse
        out[key] = item
    return out
