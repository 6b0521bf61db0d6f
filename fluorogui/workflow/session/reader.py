"""The session's reading side: frame numbers, views and components, each frame's images
(distortion-corrected, cached), the meshes (cached), the stored poses with their
stand-ins, and how far the work on each frame has got. A part of ``Session``; it reads
the project and the cache it is given and changes nothing.
"""
from __future__ import annotations

import enum
from pathlib import Path

import numpy as np

from fluorogui.core.projection.geometry import triangulate
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.records import PoseRecord, Project
from fluorogui.io.corrections import read_view_image
from fluorogui.io.errors import InputError
from fluorogui.io.meshes.model import prepared_model, read_model
from fluorogui.workflow.session.cache import SessionCache

COMPONENT_ORDER = ("femoral", "tibial")
#: Default depth of a model along a single view's central ray, as a fraction of the source-intensifier distance.
SINGLE_PLANE_DEPTH = 0.85


class FrameState(enum.IntEnum):
    """How far the work on one frame has got (the timeline's colours)."""

    EMPTY = 0  # no outline, no pose
    OUTLINED = 1  # at least one outline or placed pose
    MATCHED = 2  # every component matched and passing its checks
    REVIEWED = 3  # every component accepted by the user
    NEEDS_REVIEW = 4  # a component failed its checks (or could not be matched)



class Reader:
    """Frames, views, components, images, meshes and poses of one project.

    Parameters
    ----------
    project : fluorogui.core.records.Project
    cache : SessionCache
        Where images and meshes are kept once loaded.
    """

    def __init__(self, project: Project, cache: SessionCache) -> None:
        self.project = project
        self.cache = cache

    @property
    def frames(self) -> list[int]:
        """The frame numbers, in order (a copy)."""
        return list(self.project.frames)

    @property
    def views(self):
        """The calibrated views (:class:`~fluorogui.core.projection.geometry.View`), one per camera."""
        return list(self.project.views)

    @property
    def n_views(self) -> int:
        return len(self.project.views)

    def has_frame(self, frame: int) -> bool:
        return frame in self.project.frames

    def index_of(self, frame: int) -> int:
        """Position of a frame number in the project's frame list (KeyError if absent)."""
        try:
            return self.project.frames.index(frame)
        except ValueError:
            raise KeyError(f"frame {frame} is not in the project") from None

    def neighbour(self, frame: int, step: int) -> int:
        """The frame ``step`` places before/after ``frame`` (clamped to the first/last)."""
        frames = self.project.frames
        i = min(max(self.index_of(frame) + step, 0), len(frames) - 1)
        return frames[i]

    def components(self) -> list[str]:
        """The components with a model, femoral first, then tibial, then any others."""
        names = [m.component for m in self.project.models]
        return sorted(names, key=lambda n: (COMPONENT_ORDER.index(n) if n in COMPONENT_ORDER else 99, n))

    def image_path(self, frame: int, view: int) -> Path | None:
        """The image file of a frame in a view (None when that camera has no image for it)."""
        if view >= len(self.project.sequences) or frame not in self.project.frames:
            return None
        paths = self.project.sequences[view].paths
        i = self.project.frames.index(frame)
        return paths[i] if i < len(paths) else None

    def image_paths(self, frame: int) -> list[Path | None]:
        return [self.image_path(frame, v) for v in range(self.n_views)]

    def image(self, frame: int, view: int) -> np.ndarray:
        """One image of a frame, distortion-corrected for its view (cached).

        Parameters
        ----------
        frame : int
            A frame number.
        view : int
            The view's index (0 for the first camera).

        Returns
        -------
        numpy.ndarray
            2-D float32 in [0, 1], indexed ``[v, u]``.

        Raises
        ------
        fluorogui.io.errors.InputError
            The file cannot be read, or the camera has no image for this frame.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.image(0, 1).shape
        (256, 256)
        """
        path = self.image_path(frame, view)
        if path is None:
            n = len(self.project.sequences[view].paths) if view < len(self.project.sequences) else 0
            raise InputError(f"view {view + 1}", f"no image for frame {frame} (this camera has {n} images)")
        views = self.project.views
        return self.cache.image(path, lambda: read_view_image(path, views[view] if view < len(views) else None),
                                self.n_views)

    def images(self, frame: int) -> list[np.ndarray]:
        """The images of a frame, one per view (see :meth:`image`).

        Raises
        ------
        fluorogui.io.errors.InputError
            An image cannot be read or is missing.
        """
        return [self.image(frame, v) for v in range(self.n_views)]

    def raw_mesh(self, component: str) -> tuple[np.ndarray, np.ndarray]:
        """Vertices and faces of a component's mesh in its local frame; raises InputError."""
        if component not in self.cache.raw_meshes:
            entry = self.project.model(component)
            if entry is None:
                raise KeyError(component)
            self.cache.raw_meshes[component] = read_model(entry.mesh_path, entry.local_frame)
        return self.cache.raw_meshes[component]

    def mesh(self, component: str) -> PreparedMesh:
        """The component's mesh prepared for matching (cached).

        Parameters
        ----------
        component : str
            ``"femoral"``, ``"tibial"`` or another model's name.

        Returns
        -------
        fluorogui.core.projection.mesh.PreparedMesh
            Vertices (mm, the model's frame), faces, normals and edge adjacency.

        Raises
        ------
        fluorogui.io.errors.InputError
            The mesh file cannot be read or is not an implant-sized closed surface.
        KeyError
            The session has no such component.
        """
        if component not in self.cache.meshes:
            self.cache.meshes[component] = prepared_model(self.project.model(component).mesh_path,
                                                          *self.raw_mesh(component))
        return self.cache.meshes[component]

    # -- poses ---------------------------------------------------------------------------------
    def pose_record(self, component: str, frame: int) -> PoseRecord | None:
        """The stored pose with its status, reason, review flag and match record, or None.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> record = session.pose_record("femoral", 0)
        >>> str(record.status), record.reviewed
        ('placed', False)
        """
        return self.project.poses.get((frame, component))

    def pose(self, component: str, frame: int) -> np.ndarray:
        """The component's pose in a frame, or the best stand-in for one.

        Its own stored pose; else the nearest earlier (then later) frame's; else a default
        that puts the model where the views' central rays meet (one view: on its central
        ray at 85 % of the source-intensifier distance).

        Parameters
        ----------
        component : str
        frame : int

        Returns
        -------
        numpy.ndarray
            ``(x, y, z, alpha, beta, gamma)`` in mm and degrees: ``X = R m + t`` with
            ``R = Ry(beta) Rz(gamma) Rx(alpha)``.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.pose("tibial", 0).round(1).tolist()
        [2.5, -4.9, -15.0, -1.2, 2.1, 4.2]
        """
        record = self.project.poses.get((frame, component))
        if record is not None:
            return record.pose.copy()
        frames = self.project.frames
        if frame in frames:
            i = frames.index(frame)
            for j in list(range(i - 1, -1, -1)) + list(range(i + 1, len(frames))):
                other = self.project.poses.get((frames[j], component))
                if other is not None:
                    return other.pose.copy()
        return self.default_pose(component)

    def default_pose(self, component: str) -> np.ndarray:
        views = self.project.views
        if len(views) >= 2:
            centres = [(np.asarray(v.image_size, dtype=float) - 1) / 2 for v in views[:2]]
            point, _ = triangulate(views[:2], centres)
        elif views:  # single plane: on the central ray, where a knee usually sits (~85% of the way)
            point = views[0].source + views[0].normal * SINGLE_PLANE_DEPTH * views[0].distance
        else:
            point = np.zeros(3)
        centroid = np.zeros(3)
        try:
            centroid = self.mesh(component).centroid
        except (InputError, KeyError):
            pass
        return np.concatenate([point - centroid, np.zeros(3)])

    # -- progress of the work --------------------------------------------------------------------
    def frame_state(self, frame: int) -> FrameState:
        """How far the work on a frame has got (the timeline's colour).

        Returns
        -------
        FrameState
            ``NEEDS_REVIEW`` if any component needs review; ``REVIEWED`` if every
            component is matched and accepted; ``MATCHED`` if every one is matched;
            ``OUTLINED`` if any component has an outline or a pose in the frame (placed
            by hand, by *find* or from a file: the timeline's "outlined or placed");
            else ``EMPTY``.
        """
        names = self.components()
        if not names:
            return FrameState.EMPTY
        records = [self.project.poses.get((frame, c)) for c in names]
        if any(r is not None and r.needs_review for r in records):
            return FrameState.NEEDS_REVIEW
        if all(r is not None and r.is_matched for r in records):
            return FrameState.REVIEWED if all(r.reviewed for r in records) else FrameState.MATCHED
        if any(r is not None for r in records) or any(
                (frame, v, c) in self.project.records for v in range(self.n_views) for c in names):
            return FrameState.OUTLINED
        return FrameState.EMPTY

    def frame_states(self) -> list[FrameState]:
        return [self.frame_state(f) for f in self.project.frames]
