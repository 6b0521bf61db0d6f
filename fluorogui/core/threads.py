"""Work done once per view (segmenting an image, projecting a silhouette) run side by side.

A frame's views are independent until their results meet, and most of each view's work
is OpenCV and numpy on whole arrays, which let another thread run meanwhile. On the
2-core machine two threads segmented a real frame's two views in 40-52 ms where one took
72-78 ms. ``each_view`` gives the same results in the same order as a plain loop, and an
error in a view is raised as the loop would raise it (the first view's first).

``set_threads(1)`` runs everything on the caller's thread (worker processes that already
keep every core busy do), and so does the environment variable
``FLUOROGUI_VIEW_THREADS=1`` (read at import; the default is two threads, or one on a
one-core machine). A forked child starts without the parent's threads and makes its own
when it needs them.

The BLAS under numpy and SciPy (OpenBLAS in their wheels) starts threads of its own for
every matrix product past a small size and keeps them spinning between products. Beside
the view threads, other processes, or another BLAS thread, they only wait on each other:
the rim fit's template products (``core.outlines.rim``) took 16-18 ms of CPU per product with
OpenBLAS's threads and 1.5-1.8 ms with one (2 cores, other work on the machine). So the work
here runs BLAS on one thread per caller (``single_threaded_blas``, called where the frame
matcher and the view helpers start); ``FLUOROGUI_BLAS_THREADS=N`` leaves N. The products
split rows and columns among BLAS threads, never a sum, so the numbers are the same.
OpenCV's own thread pool does the same beside the view threads (Canny, the distance
transform, the blur of every crop): with one thread the 100 segmentations of the real
consecutive frames took 2.86 CPU-s instead of 3.45 at the same wall time, and frames
51-69 4.3-5.4 CPU-s instead of 5.6-6.4, the same poses; it runs on one thread from the
same places (``FLUOROGUI_OPENCV_THREADS=N`` leaves N).
"""
from __future__ import annotations

import ctypes
import glob
import os
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Iterable, TypeVar

T = TypeVar("T")
R = TypeVar("R")


def _threads_from_environment() -> int:
    try:
        return max(1, int(os.environ.get("FLUOROGUI_VIEW_THREADS", "")))
    except ValueError:
        return min(2, os.cpu_count() or 1)


_threads = _threads_from_environment()
_pool: ThreadPoolExecutor | None = None
_lock = threading.Lock()
_local = threading.local()
_PREFIX = "fluorogui-view"


_blas_done: set[str] = set()  # the BLAS libraries already told


def _blas_libraries() -> list[str]:
    """The OpenBLAS libraries loaded in this process: from /proc/self/maps (Linux), else
    from the numpy and SciPy wheels' library folders."""
    try:
        with open("/proc/self/maps") as maps:
            return sorted({line.split()[-1] for line in maps if "openblas" in line.lower() and "/" in line})
    except OSError:
        found = []
        for module in ("numpy", "scipy"):
            loaded = sys.modules.get(module)
            if loaded is not None and getattr(loaded, "__file__", None):
                base = os.path.dirname(os.path.dirname(loaded.__file__))
                for folder in (f"{module}.libs", os.path.join(module, ".dylibs")):
                    found += glob.glob(os.path.join(base, folder, "*openblas*"))
        return sorted(found)


def single_threaded_blas() -> None:
    """Run the loaded OpenBLAS libraries' products on one thread each (or on
    ``FLUOROGUI_BLAS_THREADS``), once per library; other BLAS libraries are left as they are.
    OpenCV's own threads too (``FLUOROGUI_OPENCV_THREADS``, default one)."""
    _single_threaded_opencv()
    try:
        n = max(1, int(os.environ.get("FLUOROGUI_BLAS_THREADS", "1")))
    except ValueError:
        n = 1
    for path in _blas_libraries():
        if path in _blas_done:
            continue
        _blas_done.add(path)
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix in ("scipy_", ""):
            for suffix in ("64_", "", "_"):
                setter = getattr(lib, f"{prefix}openblas_set_num_threads{suffix}", None)
                if setter is not None:
                    setter(ctypes.c_int(n))
                    break
            else:
                continue
            break


def _single_threaded_opencv() -> None:
    try:
        n = max(1, int(os.environ.get("FLUOROGUI_OPENCV_THREADS", "1")))
    except ValueError:
        n = 1
    import cv2

    if cv2.getNumThreads() != n:
        cv2.setNumThreads(n)


def set_threads(n: int) -> None:
    """Views run on up to ``n`` threads from now on (1: on the caller's thread only)."""
    global _threads, _pool
    with _lock:
        _threads = max(1, int(n))
        if _pool is not None:
            _pool.shutdown(wait=False)
            _pool = None


def is_view_thread_name(name: str) -> bool:
    """Is the thread of this name one of ``each_view``'s helpers (idle between calls)?"""
    return name.startswith(_PREFIX)


def each_view(fn: Callable[[T], R], items: Iterable[T]) -> list[R]:
    """``[fn(x) for x in items]``, the items after the first on helper threads while the
    caller's thread does the first."""
    items = list(items)
    if not _blas_done:
        single_threaded_blas()
    if _threads < 2 or len(items) < 2 or getattr(_local, "helper", False):
        return [fn(x) for x in items]  # (a helper waiting on helpers could wait forever)
    pool = _helpers()
    futures = [pool.submit(fn, x) for x in items[1:]]
    try:
        first = fn(items[0])
    finally:
        for f in futures:  # nothing of this call runs on after it returns or raises
            f.exception()
    return [first] + [f.result() for f in futures]


def _helpers() -> ThreadPoolExecutor:
    global _pool
    with _lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(_threads - 1, thread_name_prefix=_PREFIX, initializer=_mark)
        return _pool


def _mark() -> None:
    _local.helper = True


def _forget_pool() -> None:  # in a forked child: the parent's threads are not there
    global _pool, _lock
    _pool, _lock = None, threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)

__all__ = ["each_view", "is_view_thread_name", "set_threads", "single_threaded_blas"]
