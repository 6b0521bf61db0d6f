"""The one error type of the io layer, plus the safe-write helper every writer shares.

``InputError(path, problem)`` reads as a single line ``"<path>: <problem>"`` so the CLI can
print it on stderr and the GUI can show it in a dialog as is.
"""
from __future__ import annotations

import errno
import os
import shutil
import tempfile
from pathlib import Path


class InputError(Exception):
    """A file that cannot be read, written or understood."""

    def __init__(self, path, problem: str):
        self.path = str(path)
        self.problem = " ".join(str(problem).split())  # always one line
        super().__init__(self.path, self.problem)

    def __str__(self) -> str:
        return f"{self.path}: {self.problem}"


_OS_PROBLEMS = {
    errno.ENOSPC: "disk full",
    errno.EDQUOT: "disk quota exceeded",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.EROFS: "read-only file system",
    errno.ENOENT: "file or folder not found",
    errno.EISDIR: "is a folder, not a file",
    errno.ENOTDIR: "a part of the path is not a folder",
}


def describe_os_error(exc: OSError) -> str:
    """Short human wording of an OSError (no path, no errno number)."""
    if exc.errno in _OS_PROBLEMS:
        return _OS_PROBLEMS[exc.errno]
    return exc.strerror or str(exc) or type(exc).__name__


def atomic_write_text(path, text: str, backup: bool = False) -> None:
    """Write ``text`` to ``path`` so that a failure leaves any previous file intact.

    The text goes to a temporary file in the same folder, is flushed and fsynced, and then
    replaces the target with ``os.replace``. With ``backup`` the previous file is first
    copied to ``<name>.bak``. Any OSError becomes an InputError naming ``path``.
    """
    path = Path(path)
    tmp_name = None
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        if backup and path.is_file():
            shutil.copy2(path, path.with_name(path.name + ".bak"))
        os.replace(tmp_name, path)
        tmp_name = None
        _fsync_folder(path.parent)
    except OSError as exc:
        raise InputError(path, f"could not save: {describe_os_error(exc)}") from None
    finally:
        if tmp_name is not None:
            try:
                os.unlink(tmp_name)
            except OSError:
                pass


def _fsync_folder(folder: Path) -> None:
    """Make the rename durable where the platform allows it (POSIX); ignore elsewhere."""
    if os.name != "posix":
        return
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
