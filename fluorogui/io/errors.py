"""The one error type of the io layer, its one warning (an input repaired, or accepted with
a note) and the words for operating-system errors (the opening and writing of files every
format shares is in ``fluorogui.io.files``).

``InputError(path, problem)`` reads as a single line ``"<path>: <problem>"`` so the CLI can
print it on stderr and the GUI can show it in a dialog as is; ``collected_input_warnings``
gathers the warnings for a caller that shows them itself (the desktop app's dialog).
"""
from __future__ import annotations

import errno
import warnings
from contextlib import contextmanager


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
    errno.EFBIG: "file too large (a file size limit was reached)",
}


def describe_os_error(exc: OSError) -> str:
    """Short human wording of an OSError (no path, no errno number)."""
    if exc.errno in _OS_PROBLEMS:
        return _OS_PROBLEMS[exc.errno]
    return exc.strerror or str(exc) or type(exc).__name__


class InputWarning(UserWarning):
    """An input that was read, but not as it stood: repaired, or accepted in a form its
    format does not quite allow. ``str`` is one line ``"<path>: <what was done>"``; the
    command line prints it on stderr (``cli.inputs.input_warnings_on_stderr``)."""

    def __init__(self, path, problem: str):
        self.path = str(path)
        self.problem = " ".join(str(problem).split())
        super().__init__(self.path, self.problem)

    def __str__(self) -> str:
        return f"{self.path}: {self.problem}"


def warn_input(path, problem: str) -> None:
    """Emit an InputWarning about ``path``."""
    warnings.warn(InputWarning(path, problem), stacklevel=3)


@contextmanager
def collected_input_warnings():
    """While the block runs, every ``InputWarning`` is added (its one line) to the list the
    block gets, each once, instead of being emitted; other warnings go on as before."""
    notes: list[str] = []
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def collect(message, category, filename, lineno, file=None, line=None):  # warnings.showwarning's signature
            if issubclass(category, InputWarning):
                if str(message) not in notes:
                    notes.append(str(message))
            else:
                shown(message, category, filename, lineno, file, line)

        warnings.showwarning = collect
        warnings.simplefilter("always", InputWarning)
        yield notes
