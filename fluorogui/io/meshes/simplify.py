"""Models finer than the matcher needs, simplified instead of refused.

A model of more than ``headers.MAX_MODEL_FACES`` triangles costs the matcher memory for
nothing (an implant needs some 10^4 to 10^5): it is simplified to ``SIMPLIFIED_FACES``
with ``fast-simplification`` (the quadric edge-collapse decimator pyvista uses; Garland &
Heckbert 1997), and the simplification's surface error is measured and stated: the
distance from the original surface's vertices to the simplified surface and back
(``core.projection.nearest``, exact point-to-triangle distances), its largest value and its
RMS, over all vertices or an even sample of ``ERROR_SAMPLES`` of them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fluorogui.core.projection.nearest import TriangleSurface

#: the matcher's need: the real femoral component has 73,000 triangles
SIMPLIFIED_FACES = 100_000
#: vertices measured each way for the surface error
ERROR_SAMPLES = 50_000


@dataclass(frozen=True)
class Simplification:
    """What a simplification did: faces before and after, and the surface error (mm)."""

    faces_before: int
    faces_after: int
    max_error_mm: float
    rms_error_mm: float
    sampled: bool

    def describe(self) -> str:
        sample = " (over a sample of the vertices)" if self.sampled else ""
        return (f"simplified from {self.faces_before:,} to {self.faces_after:,} triangles for matching "
                f"(fast-simplification); surface error {self.max_error_mm:.3g} mm at most, "
                f"{self.rms_error_mm:.2g} mm RMS{sample}")


def simplify(vertices: np.ndarray, faces: np.ndarray, target_faces: int = SIMPLIFIED_FACES
             ) -> tuple[np.ndarray, np.ndarray, Simplification]:
    """The mesh simplified to about ``target_faces`` triangles, with its surface error."""
    import fast_simplification

    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    new_v, new_f = fast_simplification.simplify(v, f, target_count=int(target_faces))
    new_v = np.asarray(new_v, dtype=np.float64)
    new_f = np.asarray(new_f, dtype=np.int64).reshape(-1, 3)
    used = np.unique(new_f)  # collapsed vertices can be left unreferenced
    remap = np.full(len(new_v), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    new_v, new_f = new_v[used], remap[new_f]
    rng = np.random.default_rng(0)

    def sample(points: np.ndarray) -> np.ndarray:
        return points if len(points) <= ERROR_SAMPLES else points[rng.choice(len(points), ERROR_SAMPLES, replace=False)]

    there = TriangleSurface(new_v, new_f).closest(sample(v[np.unique(f)]))[0]
    back = TriangleSurface(v, f).closest(sample(new_v))[0]
    distances = np.concatenate([there, back])
    report = Simplification(len(f), len(new_f), float(distances.max()), float(np.sqrt(np.mean(distances ** 2))),
                            len(v) > ERROR_SAMPLES or len(new_v) > ERROR_SAMPLES)
    return new_v, new_f, report
