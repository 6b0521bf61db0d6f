"""What a session keeps so as not to load or compute it twice: images, meshes, outline
splines and the default anatomical frames, each in a field of its own and cleared in one
place (``SessionCache.clear``). Images are read from worker threads too, so they sit
behind a lock and are dropped oldest first past a limit."""
from __future__ import annotations

import threading
from collections import OrderedDict
from pathlib import Path
from typing import Callable

import numpy as np

from fluorogui.core.projection.mesh import PreparedMesh

#: frames of images kept per view
IMAGE_CACHE_FRAMES = 6


class SessionCache:
    """The session's caches; every part that caches something keeps it here.

    Attributes
    ----------
    meshes : dict of str to PreparedMesh
        Meshes prepared for matching, by component.
    raw_meshes : dict of str to (vertices, faces)
        Meshes as read, in the model's local frame, by component.
    splines : dict
        ``(frame, view, component)`` to ``(record, spline)``: a spline is fitted once per
        outline record.
    anatomical_frames : dict of str to numpy.ndarray
        The default anatomical frame found on each component's mesh.
    """

    def __init__(self) -> None:
        self._images: OrderedDict[Path, np.ndarray] = OrderedDict()
        self._lock = threading.RLock()
        self.meshes: dict[str, PreparedMesh] = {}
        self.raw_meshes: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self.splines: dict = {}
        self.anatomical_frames: dict[str, np.ndarray] = {}

    def image(self, path: Path, load: Callable[[], np.ndarray], views: int) -> np.ndarray:
        """The image of ``path``, loaded by ``load()`` when not kept; at most
        ``IMAGE_CACHE_FRAMES`` frames of ``views`` images are kept, the oldest dropped."""
        with self._lock:
            if path in self._images:
                self._images.move_to_end(path)
                return self._images[path]
        image = load()  # outside the lock: another thread may read meanwhile
        with self._lock:
            self._images[path] = image
            while len(self._images) > IMAGE_CACHE_FRAMES * max(1, views):
                self._images.popitem(last=False)
        return image

    def forget_mesh(self, component: str) -> None:
        """Drop what was made from a component's mesh file (its file changed): the meshes
        and the anatomical frame found on it."""
        self.raw_meshes.pop(component, None)
        self.meshes.pop(component, None)
        self.anatomical_frames.pop(component, None)

    def clear(self) -> None:
        """Drop everything (another project)."""
        with self._lock:
            self._images.clear()
        self.meshes.clear()
        self.raw_meshes.clear()
        self.splines.clear()
        self.anatomical_frames.clear()
