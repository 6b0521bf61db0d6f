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
"""
from __future__ import annotations

import os
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

__all__ = ["each_view", "is_view_thread_name", "set_threads"]
