"""*Find implants* in workflow terms: where is each component in a frame, with no start.

A thin layer over ``fluorogui.core.search.find.find_components`` (dark regions, which is
which, an orientation search and a refinement on Canny outlines) that turns its answer
into ``Placement`` records of the frame: a component is placed only when the search is confident;
otherwise the placement says why not and what overlap it reached, and nothing is
stored as if it were right.
"""
from __future__ import annotations

import time
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.search.find import Placement, find_components, near_candidates


def find_in_frame(frame: int, images: Sequence[np.ndarray], views: Sequence[View], meshes: dict[str, PreparedMesh],
                  *, near: dict[str, np.ndarray] | None = None, progress: Callable[[float, str], None] | None = None,
                  cancel: Callable[[], bool] | None = None) -> dict[str, Placement]:
    """Placements of ``meshes`` (name -> mesh) in one frame (``Placement.frame`` set);
    ``near`` limits the search to around predicted poses. Raises ``Cancelled`` when
    ``cancel()`` turns true."""
    t0 = time.perf_counter()
    found = find_components(list(images), list(views), meshes, near=near, progress=progress, cancel=cancel)
    out = {}
    for name in meshes:
        p = found.get(name)
        if p is None:
            p = Placement(name, None, False, [], float("nan"), [], "the search returned nothing",
                          time.perf_counter() - t0)
        out[name] = replace(p, frame=frame, found=bool(p.found),
                            pose=None if p.pose is None else np.asarray(p.pose, float),
                            iou=[float(v) for v in p.iou], reason="" if p.found else p.reason)
    return out


def near_search(views: Sequence[View], settings=None):
    """A ``find_near(images, component, mesh, pose, cancel) -> poses, pose or None`` for
    recovery (None when ``settings.tracking.find_near`` is off). Near a predicted ``pose``:
    the search's candidates, best first (``near_candidates``: without its Canny fit, which
    the match from each makes). With ``pose`` None, a search of the whole image: its
    placement, which is returned even when the search is not confident of it (the match
    from it is judged by its own checks)."""
    if settings is not None and not settings.tracking.find_near:
        return None

    def find_near(images, component: str, mesh: PreparedMesh, pose, cancel=None):
        try:
            if pose is not None:
                return near_candidates(list(images), list(views), mesh, pose, cancel=cancel) or None
            found = find_components(list(images), list(views), {component: mesh}, cancel=cancel)
        except ValueError:  # Cancelled passes through to the caller
            return None
        p = found.get(component)
        return None if p is None or p.pose is None else np.asarray(p.pose, float)

    return find_near


__all__ = ["find_in_frame", "near_search"]
