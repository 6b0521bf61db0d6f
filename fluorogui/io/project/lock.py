"""Who is working on a project: a lock file beside it (``<name>.fluoro.lock``).

The desktop app holds the lock while a project is open; ``fluorogui track`` / ``find`` /
``batch`` hold it while they write. A second writer is refused with a message saying who
holds the lock (program, process id, host, user, since when) instead of both saving over
each other. A lock left by a process that no longer runs on this host is stale and is
taken over. The lock file is created atomically (``O_EXCL``) and holds one JSON object.
"""
from __future__ import annotations

import getpass
import json
import os
import socket
import time
from pathlib import Path

from fluorogui.io.errors import InputError, describe_os_error
from fluorogui.io.files import process_alive

LOCK_SUFFIX = ".lock"
_HELD: dict[Path, int] = {}  # lock files this process holds -> how many holders


class ProjectLocked(InputError):
    """The project is locked by another live process; ``holder`` says who."""

    def __init__(self, path, holder: dict):
        self.holder = holder
        super().__init__(path, f"is in use by {describe_holder(holder)}; close it there first")


def lock_path(project_path) -> Path:
    p = Path(project_path)
    return p.with_name(p.name + LOCK_SUFFIX)


def describe_holder(holder: dict) -> str:
    since = holder.get("since")
    when = time.strftime("%Y-%m-%d %H:%M", time.localtime(since)) if isinstance(since, (int, float)) else "?"
    return (f"{holder.get('program', 'another program')} (process {holder.get('pid', '?')} of "
            f"{holder.get('user', '?')} on {holder.get('host', '?')}, since {when})")


def read_holder(project_path) -> dict | None:
    """The lock's content, or None when the project is not locked (or the file is unreadable)."""
    try:
        data = json.loads(lock_path(project_path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _is_stale(holder: dict | None) -> bool:
    if holder is None:
        return True  # unreadable or empty: a crash while writing it
    return holder.get("host") == socket.gethostname() and not process_alive(holder.get("pid"))


class ProjectLock:
    """``with ProjectLock(path, "fluorogui track"):`` - raises ProjectLocked when another
    live process holds the project; re-entrant for the same process."""

    def __init__(self, project_path, program: str = "fluorogui", token: str | None = None) -> None:
        self.project_path = Path(project_path)
        self.path = lock_path(project_path)
        self.program = program
        self.token = token  # a retried batch task takes over a lock its own run left (another host)
        self.held = False

    def acquire(self) -> "ProjectLock":
        me = {"program": self.program, "pid": os.getpid(), "host": socket.gethostname(),
              "user": _user(), "since": time.time(), "token": self.token}
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                holder = read_holder(self.project_path)
                if holder is not None and holder.get("pid") == os.getpid() and \
                        holder.get("host") == me["host"] and _HELD.get(self.path.absolute()):
                    _HELD[self.path.absolute()] += 1  # this process already holds it
                    self.held = True
                    return self
                ours = self.token is not None and holder is not None and holder.get("token") == self.token
                if not ours and not _is_stale(holder):
                    raise ProjectLocked(self.project_path, holder) from None
                try:
                    os.unlink(self.path)  # stale: the holder is gone
                except FileNotFoundError:
                    pass
                except OSError as exc:
                    raise InputError(self.path, f"cannot remove a stale lock: {describe_os_error(exc)}") from None
                continue
            except OSError as exc:
                raise InputError(self.path, f"cannot create the lock file: {describe_os_error(exc)}") from None
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                json.dump(me, handle)
            _HELD[self.path.absolute()] = 1
            self.held = True
            return self
        raise InputError(self.path, "cannot take the lock (another process keeps recreating it)")

    def release(self) -> None:
        if not self.held:
            return
        self.held = False
        key = self.path.absolute()
        _HELD[key] = _HELD.get(key, 1) - 1
        if _HELD[key] > 0:
            return
        del _HELD[key]
        holder = read_holder(self.project_path)
        if holder is not None and holder.get("pid") == os.getpid():
            try:
                os.unlink(self.path)
            except OSError:
                pass

    def __enter__(self) -> "ProjectLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _user() -> str:
    try:
        return getpass.getuser()
    except Exception:  # noqa: BLE001 - no user name is not a reason to fail
        return "?"
