"""*Find implants* in workflow terms: where is each component in a frame, with no start.

A thin layer over ``fluorogui.core.initialise.find_components`` (dark regions, which is
which, an orientation search and a refinement on Canny outlines) that turns its answer
into ``Placement`` records: a component is placed only when the search is confident;
otherwise the placement says why not and what overlap it reached, and nothing is
stored as if it were right.
"""
from __future__ import annotations

import time
from typing import Callable, Sequence

import numpy as np

from fluorogui.core.geometry import View
from fluorogui.core.initialise import SearchCancelled
from fluorogui.core.mesh import PreparedMesh
from fluorogui.workflow.results import Placement


def find_in_frame(frame: int, images: Sequence[np.ndarray], views: Sequence[View], meshes: dict[str, PreparedMesh],
                  near: dict[str, np.ndarray] | None = None, progress: Callable[[float, str], None] | None = None,
                  cancel: Callable[[], bool] | None = None) -> dict[str, Placement]:
    """Placements of ``meshes`` (name -> mesh) in one frame; ``near`` limits the search to
    around predicted poses. Raises ``SearchCancelled`` when cancelled."""
    from fluorogui.core.initialise import find_components

    t0 = time.perf_counter()
    found = find_components(list(images), list(views), meshes, near=near, progress=progress, cancel=cancel)
    out = {}
    for name in meshes:
        p = found.get(name)
        if p is None:
            out[name] = Placement(name, frame, None, False, [], "the search returned nothing",
                                  time.perf_counter() - t0)
            continue
        out[name] = Placement(name, frame, None if p.pose is None else np.asarray(p.pose, float), bool(p.found),
                              [float(v) for v in p.iou], p.reason if not p.found else "", float(p.seconds))
    return out


def near_search(views: Sequence[View]):
    """A ``find_near(images, component, mesh, pose, cancel) -> pose or None`` for tracking
    recovery: the search limited to around the predicted pose (the whole image when
    ``pose`` is None). A placement the search is not confident of is still returned: the
    match from it is judged by its own checks."""

    def find_near(images, component: str, mesh: PreparedMesh, pose, cancel=None):
        from fluorogui.core.initialise import find_components

        near = None if pose is None else {component: pose}
        try:
            found = find_components(list(images), list(views), {component: mesh}, near=near, cancel=cancel)
        except ValueError:  # SearchCancelled passes through to the caller
            return None
        p = found.get(component)
        return None if p is None or p.pose is None else np.asarray(p.pose, float)

    return find_near


__all__ = ["SearchCancelled", "find_in_frame", "near_search"]
