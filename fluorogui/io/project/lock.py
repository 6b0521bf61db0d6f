"""Who is working on a project: an operating-system lock beside it, and a note of the holder.

The desktop app holds the lock while a project is open; ``fluorogui track`` / ``find`` /
``batch`` hold it while they write. A second writer is refused with a message saying who
holds the lock (program, process id, host, user, since when) instead of both saving over
each other.

Two files beside ``<name>.fluoro`` while a program has it:

* ``.<name>.fluoro.guard`` carries the lock itself: an exclusive operating-system lock
  (``portalocker``: ``flock`` on POSIX, ``msvcrt.locking`` on Windows) that only one
  process can hold and that the system lets go of when the process ends, however it
  ends. So two programs that open the project at the same moment, or take over a stale
  lock at the same moment, cannot both win, and a crash never leaves the project locked.
* ``<name>.fluoro.lock`` is the note of who holds it: one JSON object, written atomically
  after the lock is taken, so a reader sees all of it or nothing. It decides nothing
  while the lock is held; a reader that finds the lock held but the note not yet
  written (or just removed) asks again for a moment, then says "another program".

A note without a held lock is stale - its process ended - unless it names a process that
still runs (started at the time the note says; ``psutil``, which answers on Windows too)
or a process on another host (which cannot be asked): an earlier fluorogui, which locked
by the note alone, may hold the project. A batch run's retried task (same ``token``)
takes over the note its own dead worker left on another host. Within one process the lock
is re-entrant. Where the file system offers no locks (rare: it is logged), the note alone
protects the project, which does not exclude two programs starting at the same moment.
"""
from __future__ import annotations

import getpass
import json
import logging
import os
import socket
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import portalocker
import psutil

from fluorogui.io.errors import InputError, describe_os_error
from fluorogui.io.files import atomic_write_text, process_alive

LOCK_SUFFIX = ".lock"
GUARD_SUFFIX = ".guard"
#: how long a refused taker waits for a holder's note still being written (seconds)
NOTE_PATIENCE_S = 1.0
_log = logging.getLogger(__name__)


@dataclass
class _Held:
    count: int  # holders in this process
    fd: int | None  # the guard file, locked (None where the file system has no locks)


_HELD: dict[Path, _Held] = {}  # projects this process holds, by absolute lock path
_HELD_LOCK = threading.Lock()


def _forget_after_fork() -> None:
    """A forked child holds nothing: its copies of the guard files are closed (which does
    not release the parent's locks; unlocking would) and it takes its own locks."""
    global _HELD_LOCK
    _HELD_LOCK = threading.Lock()
    for held in _HELD.values():
        if held.fd is not None:
            try:
                os.close(held.fd)
            except OSError:
                pass
    _HELD.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_after_fork)


class ProjectLocked(InputError):
    """The project is locked by another live process; ``holder`` says who."""

    def __init__(self, path, holder: dict):
        self.holder = holder
        super().__init__(path, f"is in use by {describe_holder(holder)}; close it there first")


def lock_path(project_path) -> Path:
    """The holder's note: ``<name>.fluoro.lock``."""
    p = Path(project_path)
    return p.with_name(p.name + LOCK_SUFFIX)


def guard_path(project_path) -> Path:
    """The file the operating-system lock is taken on: ``.<name>.fluoro.guard``."""
    p = Path(project_path)
    return p.with_name(f".{p.name}{GUARD_SUFFIX}")


def describe_holder(holder: dict) -> str:
    if not holder:
        return "another program (it is taking the lock right now)"
    since = holder.get("since")
    when = time.strftime("%Y-%m-%d %H:%M", time.localtime(since)) if isinstance(since, (int, float)) else "?"
    return (f"{holder.get('program', 'another program')} (process {holder.get('pid', '?')} of "
            f"{holder.get('user', '?')} on {holder.get('host', '?')}, since {when})")


def read_holder(project_path) -> dict | None:
    """The holder's note, or None when there is none (or it cannot be read)."""
    try:
        data = json.loads(lock_path(project_path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def holder_alive(holder: dict) -> bool:
    """Whether the process a note names still runs on this host: its id is alive and,
    when the note has the process's start time, it is that process (not a new one that
    was given the same id)."""
    pid = holder.get("pid")
    if not process_alive(pid):
        return False
    started = holder.get("started")
    if pid == os.getpid() or not isinstance(started, (int, float)):
        return True
    try:
        return abs(psutil.Process(pid).create_time() - started) < 1.0
    except psutil.NoSuchProcess:
        return False
    except psutil.Error:  # not allowed to ask: assume it is the holder
        return True


def _process_started() -> float | None:
    try:
        return psutil.Process().create_time()
    except psutil.Error:
        return None


class ProjectLock:
    """``with ProjectLock(path, "fluorogui track"):`` - raises ProjectLocked when another
    live process holds the project; re-entrant for the same process."""

    def __init__(self, project_path, program: str = "fluorogui", token: str | None = None) -> None:
        self.project_path = Path(project_path)
        self.path = lock_path(project_path)
        self.guard = guard_path(project_path)
        self.program = program
        self.token = token  # a retried batch task takes over a lock its own run left (another host)
        self.held = False

    def acquire(self) -> ProjectLock:
        key = self.path.absolute()
        with _HELD_LOCK:
            held = _HELD.get(key)
            if held is not None:  # this process already holds it
                held.count += 1
                self.held = True
                return self
            fd = self._take_guard()
            try:
                holder = read_holder(self.project_path)
                if holder is not None and not self._may_take_over(holder):
                    raise ProjectLocked(self.project_path, holder)
                self._write_note()
            except BaseException:
                _let_go(self.guard, fd)
                raise
            _HELD[key] = _Held(1, fd)
            self.held = True
            return self

    def release(self) -> None:
        if not self.held:
            return
        self.held = False
        key = self.path.absolute()
        with _HELD_LOCK:
            held = _HELD.get(key)
            if held is None:
                return
            held.count -= 1
            if held.count > 0:
                return
            del _HELD[key]
            holder = read_holder(self.project_path)
            if holder is not None and holder.get("pid") == os.getpid():
                try:
                    os.unlink(self.path)
                except OSError:
                    pass
            _let_go(self.guard, held.fd)

    def __enter__(self) -> ProjectLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()

    # -- taking it ---------------------------------------------------------------------------
    def _take_guard(self) -> int | None:
        """The guard file, locked by this process; ProjectLocked when another holds it.
        None when the file system cannot lock (the note alone decides then)."""
        deadline = time.monotonic() + NOTE_PATIENCE_S
        while True:
            try:
                fd = os.open(self.guard, os.O_RDWR | os.O_CREAT | getattr(os, "O_BINARY", 0), 0o644)
            except OSError as exc:
                raise InputError(self.path, f"cannot create the lock file: {describe_os_error(exc)}") from None
            try:
                portalocker.lock(fd, portalocker.LockFlags.EXCLUSIVE | portalocker.LockFlags.NON_BLOCKING)
            except portalocker.AlreadyLocked:
                os.close(fd)
                holder = read_holder(self.project_path)
                if holder is not None and not _claims_it(holder):
                    holder = None  # a dead process's note, about to be replaced by the new holder's
                if holder is not None or time.monotonic() > deadline:
                    raise ProjectLocked(self.project_path, holder or {}) from None
                time.sleep(0.05)  # the holder is writing its note (or letting go): ask again
                continue
            except portalocker.LockException as exc:
                _log.warning("%s: no file locks here (%s); the lock file alone protects the project", self.guard, exc)
                os.close(fd)
                return None
            if _same_file(fd, self.guard):
                return fd
            _unlock_and_close(fd)  # a holder letting go removed the file after we opened it

    def _may_take_over(self, holder: dict) -> bool:
        """With the guard held: whether a note left beside the project may be replaced."""
        if self.token is not None and holder.get("token") == self.token:
            return True  # our own run's, left by a worker that died
        if holder.get("host") != socket.gethostname():
            return False  # cannot ask another host; an earlier fluorogui there may hold it
        return holder.get("pid") == os.getpid() or not holder_alive(holder)

    def _write_note(self) -> None:
        me = {"program": self.program, "pid": os.getpid(), "started": _process_started(),
              "host": socket.gethostname(), "user": _user(), "since": time.time(), "token": self.token}
        for attempt in range(5):
            try:
                atomic_write_text(self.path, json.dumps(me))
                return
            except InputError as exc:
                if attempt == 4 or os.name != "nt":
                    raise InputError(self.path, f"cannot write the lock file: {exc.problem}") from None
                time.sleep(0.02)  # Windows replaces no file another process is reading: again


def _claims_it(holder: dict) -> bool:
    """Whether a note read while the guard is held elsewhere names a plausible holder (not
    the note of a process that ended, about to be replaced)."""
    return holder.get("host") != socket.gethostname() or holder_alive(holder)


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` still names the open file (POSIX: a file can be removed while open;
    Windows removes no open file)."""
    if os.name != "posix":
        return True
    try:
        mine, now = os.fstat(fd), os.stat(path)
    except OSError:
        return False
    return (mine.st_dev, mine.st_ino) == (now.st_dev, now.st_ino)


def _unlock_and_close(fd: int) -> None:
    try:
        portalocker.unlock(fd)
    except portalocker.LockException:
        pass
    finally:
        os.close(fd)


def _let_go(guard: Path, fd: int | None) -> None:
    """Remove the guard file and release its lock. On POSIX the file goes first, while
    still locked: a process that opened it meanwhile finds it gone and opens a new one
    (``_same_file``), so no two processes ever hold locks on two files of one name.
    Windows cannot remove an open file: the lock goes first, and the file stays when
    another process has just opened it."""
    if fd is None:
        return
    if os.name == "posix":
        try:
            os.unlink(guard)
        except OSError:
            pass
        _unlock_and_close(fd)
    else:
        _unlock_and_close(fd)
        try:
            os.unlink(guard)
        except OSError:
            pass


def _user() -> str:
    try:
        return getpass.getuser()
    except Exception:  # noqa: BLE001 - no user name is not a reason to fail
        return "?"
