"""Files in and out, the same way for every format: the one opening of input files
(regular files only, size-capped, never blocking), text files, and atomic writes with a
backup that is never rewritten in place; "is this process alive" for temp files and locks.
Errors are ``fluorogui.io.errors.InputError`` naming the file.
"""
from __future__ import annotations

import os
import shutil
import stat
import tempfile
import time
from pathlib import Path

import psutil

from fluorogui.io.errors import InputError, describe_os_error


def process_alive(pid) -> bool:
    """Whether a process with this id runs on this machine (this process always does).
    ``psutil`` asks the operating system the way each one answers (``os.kill(pid, 0)``
    tells nothing on Windows)."""
    if not isinstance(pid, int) or isinstance(pid, bool) or pid <= 0:
        return False
    if pid == os.getpid():
        return True
    try:
        return psutil.pid_exists(pid)
    except (OSError, ValueError, OverflowError):
        return False


# -- reading: one opening for every loader ------------------------------------------------------
def check_input_file(path, what: str = "file") -> Path:
    """``path`` as a Path when it names a readable regular file; else InputError.

    Folders, FIFOs, sockets and devices are refused from ``stat`` alone, so nothing blocks
    (a FIFO given as a calibration used to hang forever)."""
    path = Path(path)
    try:
        info = path.stat()
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the {what}: {describe_os_error(exc)}") from None
    if stat.S_ISDIR(info.st_mode):
        raise InputError(path, f"is a folder, not a {what}")
    if not stat.S_ISREG(info.st_mode):
        raise InputError(path, f"is not a regular file (a pipe, socket or device); give a {what}")
    return path


def read_input_bytes(path, what: str = "file", max_bytes: int = 1 << 30) -> bytes:
    """The bytes of a regular file of at most ``max_bytes``, or one InputError naming it."""
    path = check_input_file(path, what)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except OSError as exc:
        raise InputError(path, f"cannot read the {what}: {describe_os_error(exc)}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):  # swapped for a pipe since the check
            raise InputError(path, f"is not a regular file; give a {what}")
        if info.st_size > max_bytes:
            raise InputError(path, f"{what} is too large ({info.st_size / 1e6:.0f} MB; at most "
                                   f"{max_bytes / 1e6:.0f} MB)")
        with os.fdopen(fd, "rb", closefd=False) as handle:
            data = handle.read(max_bytes + 1)
    except OSError as exc:
        raise InputError(path, f"cannot read the {what}: {describe_os_error(exc)}") from None
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        raise InputError(path, f"{what} is too large (more than {max_bytes / 1e6:.0f} MB)")
    return data


MAX_TABLE_BYTES = 200_000_000


def read_text_file(path, what: str = "CSV file") -> str:
    """The text of a CSV file; binary files are refused."""
    raw = read_input_bytes(path, what, MAX_TABLE_BYTES)
    if b"\x00" in raw[:65536]:
        raise InputError(path, f"binary file, not a text {what}")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(path, f"not a text {what} (not UTF-8)") from None


# -- writing: atomic, with a backup that is never rewritten in place -------------------------------
_TEMP_SUFFIX = ".tmp"
_STALE_TEMP_SECONDS = 600  # a temp file without a readable owner is stale after this long


def write_target(path) -> Path:
    """The file a write to ``path`` replaces: a symlink's final target (the link is kept)."""
    path = Path(path)
    if path.is_symlink():
        return Path(os.path.realpath(path))
    return path


def _temp_prefix(target: Path) -> str:
    return f".{target.name}."


def _new_temp(target: Path, tag: str = "") -> tuple[int, str]:
    """A temp file beside ``target`` named ``.<name>.<tag><pid>.<random>.tmp``."""
    return tempfile.mkstemp(prefix=f"{_temp_prefix(target)}{tag}{os.getpid()}.", suffix=_TEMP_SUFFIX,
                            dir=target.parent)


def clean_stale_temps(path) -> int:
    """Remove temp files an interrupted save of ``path`` left beside it (those whose writing
    process no longer runs, or old ones); returns how many were removed."""
    target = write_target(path)
    prefix = _temp_prefix(target)
    removed = 0
    try:
        entries = list(os.scandir(target.parent))
    except OSError:
        return 0
    now = time.time()
    for entry in entries:
        name = entry.name
        if not (name.startswith(prefix) and name.endswith(_TEMP_SUFFIX)):
            continue
        middle = name[len(prefix):-len(_TEMP_SUFFIX)].removeprefix("bak")
        owner = middle.split(".", 1)[0]
        try:
            if owner.isdigit():
                stale = not process_alive(int(owner))
            else:  # older versions' names carry no owner
                stale = now - entry.stat(follow_symlinks=False).st_mtime > _STALE_TEMP_SECONDS
            if stale and entry.is_file(follow_symlinks=False):
                os.unlink(entry.path)
                removed += 1
        except OSError:
            continue
    return removed


def atomic_write_text(path, text: str, backup: bool = False) -> None:
    """Write ``text`` to ``path`` so that a failure or a kill at any moment leaves the
    previous file (and its backup) whole.

    The text goes to a temporary file in the same folder, is flushed and fsynced, gets the
    previous file's mode (or the umask's default for a new file), and then replaces the
    target with ``os.replace``. With ``backup`` the previous file becomes ``<name>.bak``
    through a hard link renamed into place (a fsynced copy where links are not supported),
    so the backup is never rewritten in place. A symlinked ``path`` keeps its link: the
    file it points to is replaced. Leftover temp files of earlier interrupted saves are
    removed. Any OSError becomes an InputError naming ``path``.
    """
    path = Path(path)
    target = write_target(path)
    clean_stale_temps(target)
    tmp_name = bak_tmp = None
    try:
        mode = _mode_for(target)
        fd, tmp_name = _new_temp(target)
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
            handle.flush()
            if hasattr(os, "fchmod"):
                os.fchmod(handle.fileno(), mode)
            os.fsync(handle.fileno())
        if backup and target.is_file():
            bak_tmp = _backup_copy(target)
            os.replace(bak_tmp, target.with_name(target.name + ".bak"))
            if os.path.lexists(bak_tmp):  # rename is a no-op when both names are one file
                os.unlink(bak_tmp)
            bak_tmp = None
        os.replace(tmp_name, target)
        tmp_name = None
        _fsync_folder(target.parent)
    except OSError as exc:
        raise InputError(path, f"could not save: {describe_os_error(exc)}") from None
    finally:
        for leftover in (tmp_name, bak_tmp):
            if leftover is not None:
                try:
                    os.unlink(leftover)
                except OSError:
                    pass


def _mode_for(target: Path) -> int:
    try:
        return stat.S_IMODE(target.stat().st_mode)
    except FileNotFoundError:
        return 0o666 & ~_umask()


def _umask() -> int:
    """The process's umask, read without changing it where Linux allows (setting it, even
    briefly, would affect files other threads create meanwhile)."""
    try:
        with open("/proc/self/status", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    umask = os.umask(0o022)
    os.umask(umask)
    return umask


def _backup_copy(target: Path) -> str:
    """A temp file holding the bytes of ``target``: a hard link, or a fsynced copy."""
    fd, name = _new_temp(target, "bak")
    os.close(fd)
    try:
        os.unlink(name)
        os.link(target, name)
        return name
    except OSError:
        pass
    try:
        shutil.copy2(target, name)
        with open(name, "rb+") as handle:
            os.fsync(handle.fileno())
    except OSError:
        try:
            os.unlink(name)
        except OSError:
            pass
        raise
    return name


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


def check_output_folder(folder) -> Path | None:
    """Make ``folder`` (when given) and prove it writable, before any work starts."""
    if not folder:
        return None
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise InputError(folder, f"cannot write results here: {describe_os_error(exc)}") from None
    return folder


def check_output_file(path) -> Path:
    """Prove the folder of the file ``path`` writable (and ``path`` not a folder), before work."""
    path = Path(path)
    if path.is_dir():
        raise InputError(path, "is a folder; give a file name to write")
    if not path.parent.is_dir():
        raise InputError(path, "cannot write here: the folder does not exist")
    check_output_folder(path.parent)
    return path
