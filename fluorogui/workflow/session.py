"""The Qt-free session: one open project and everything done to it.

``Session`` is what the desktop app, the command line and scripts share (the pattern of
glue's Application or MNE's coreg under its GUI). It owns:

* the project, its file and saving (atomic, with a backup);
* frame access by frame number (the ``frame`` column of pairs.csv) - never by index;
* caches of what is costly to load (images, prepared meshes, splines);
* every edit as an undoable ``Command`` on ``history`` (poses, outlines, review flags);
  the app's Qt undo stack only mirrors it;
* the pose fallback, placement from two clicks and the orientation presets;
* the work: ``match``, ``find`` and ``track`` (see ``work.py``), each also available as a
  job that runs in a worker thread or another process and returns results that
  ``store`` puts into the project on the caller's thread.

Listeners (``session.listeners``) hear ``("pose", (frame, component))``,
``("outline", (frame, view, component))``, ``("knee", "side" | component)``,
``("project", None)`` and ``("saved", path)``. The knee's side, anatomical frames and
kinematics come from ``KneeMixin`` (``knee.py``).
"""
from __future__ import annotations

import enum
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from fluorogui.core.outlines.spline import OutlineError, OutlineSpline
from fluorogui.core.projection.geometry import triangulate
from fluorogui.core.projection.mesh import MeshError, PreparedMesh, check_plausible_mm, prepare_mesh
from fluorogui.core.projection.pose import as_pose, rotation_matrix
from fluorogui.core.records import ImageSequence, ModelEntry, OutlineRecord, PoseRecord, Project
from fluorogui.io.corrections import read_view_image
from fluorogui.io.errors import InputError
from fluorogui.io.meshes.read import load_mesh
from fluorogui.io.project.document import load_project, save_project
from fluorogui.workflow.history import Command, CommandStack
from fluorogui.workflow.knee import KneeMixin
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.settings import SETTINGS_KEY, WorkflowSettings
from fluorogui.workflow.work import WorkMixin

COMPONENT_ORDER = ("femoral", "tibial")
IMAGE_CACHE_FRAMES = 6
#: Default depth of a model along a single view's central ray, as a fraction of the source-intensifier distance.
SINGLE_PLANE_DEPTH = 0.85
ORIENTATION_PRESETS = (
    ("Upright (all angles 0)", (0.0, 0.0, 0.0)),
    ("Flexed 30°", (30.0, 0.0, 0.0)),
    ("Flexed 60°", (60.0, 0.0, 0.0)),
    ("Flexed 90°", (90.0, 0.0, 0.0)),
    ("Turned 180° about y", (0.0, 180.0, 0.0)),
)


class FrameState(enum.IntEnum):
    """How far the work on one frame has got (the timeline's colours)."""

    EMPTY = 0  # no outline, no pose
    OUTLINED = 1  # at least one outline or placed pose
    MATCHED = 2  # every component matched and passing its checks
    REVIEWED = 3  # every component accepted by the user
    NEEDS_REVIEW = 4  # a component failed its checks (or could not be matched)


def read_model(path, local_frame: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (mm, in the component's local frame) and faces of an implant mesh file: the
    one reading of a model for the app, the command line and scripts. A mesh whose size
    cannot be an implant in millimetres is refused; raises InputError naming the file."""
    vertices, faces = load_mesh(path)
    try:
        check_plausible_mm(vertices)
    except MeshError as exc:
        raise InputError(path, str(exc)) from None
    if local_frame is not None and not np.allclose(local_frame, np.eye(4)):
        vertices = vertices @ local_frame[:3, :3].T + local_frame[:3, 3]
    return vertices, faces


#: a model may have this many edges bordering one triangle (or more than two) before it is
#: taken for a triangle soup: the matcher takes every such edge as a silhouette candidate
#: in every view, which made a 400,000-triangle soup need 15 GB
MAX_OPEN_EDGES = 1000
MAX_OPEN_EDGE_SHARE = 0.05


def prepared_model(path, vertices: np.ndarray, faces: np.ndarray) -> PreparedMesh:
    """A model read by ``read_model`` prepared for matching; raises InputError naming ``path``,
    also for a model that is not a closed surface (more than ``MAX_OPEN_EDGES`` and
    ``MAX_OPEN_EDGE_SHARE`` of its edges open: a real implant model has a few dozen)."""
    try:
        mesh = prepare_mesh(vertices, faces)
    except MeshError as exc:
        raise InputError(path, str(exc)) from None
    open_edges, edges = len(mesh.open_edges), len(mesh.open_edges) + len(mesh.edges)
    if open_edges > MAX_OPEN_EDGES and open_edges > MAX_OPEN_EDGE_SHARE * edges:
        raise InputError(path, f"mesh is not a closed surface: {open_edges:,} of its {edges:,} edges border one "
                               "triangle (or more than two); an implant model is closed (is it a triangle soup?)")
    return mesh


def fitted_outline(points: np.ndarray, weights: np.ndarray | None = None) -> OutlineSpline | None:
    """The spline through an outline (with its points' weights), or None while the
    outline cannot carry one."""
    try:
        return OutlineSpline.fit(points, weights=weights)
    except (OutlineError, ValueError):
        return None


class Session(WorkMixin, KneeMixin):
    """One open project, its undo history and the work done on it."""

    def __init__(self, project: Project | None = None, path=None) -> None:
        self.project = project or Project()
        self.path: Path | None = Path(path) if path else None
        self.history = CommandStack()
        self.listeners: list[Callable[[str, object], None]] = []
        self._images: OrderedDict = OrderedDict()
        self._cache_lock = threading.RLock()
        self._meshes: dict[str, PreparedMesh] = {}
        self._raw_meshes: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._splines: dict = {}

    # -- project lifecycle ---------------------------------------------------------------------
    @classmethod
    def open(cls, path) -> "Session":
        """A session on a project file; raises InputError naming the file."""
        return cls(load_project(path), Path(path))

    @classmethod
    def of_images(cls, views, image_paths, models: dict) -> "Session":
        """A session of one frame (numbered 0): one image file per view (``FILE@N`` for a
        frame of a multi-frame file) and the models (component name -> mesh file). What
        ``fluorogui match`` works on; nothing is saved unless asked."""
        project = Project(views=list(views), sequences=[ImageSequence([Path(p)]) for p in image_paths], frames=[0],
                          models=[ModelEntry(name, Path(path)) for name, path in models.items()])
        return cls(project)

    def replace_project(self, project: Project, path=None) -> None:
        """Put another project in this session (after it loaded); clears caches and history."""
        self.project = project
        self.path = Path(path) if path else None
        with self._cache_lock:
            self._images.clear()
        self._meshes.clear()
        self._raw_meshes.clear()
        self._splines.clear()
        self.__dict__.pop("_default_frames", None)
        self.history.clear()
        self._notify("project", None)

    def save(self, path=None) -> Path:
        """Save atomically to ``path`` or the session's file (a backup of the old file is kept)."""
        target = Path(path) if path else self.path
        if target is None:
            raise ValueError("no file name to save to")
        save_project(self.project, target)
        self.path = target
        self.history.set_clean()
        self._notify("saved", target)
        return target

    @property
    def dirty(self) -> bool:
        return self.history.dirty

    def _notify(self, event: str, what) -> None:
        for listener in list(self.listeners):
            listener(event, what)

    # -- settings ----------------------------------------------------------------------------------
    @property
    def settings(self) -> WorkflowSettings:
        return WorkflowSettings.from_dict(self.project.settings.get(SETTINGS_KEY))

    def set_settings(self, settings: WorkflowSettings) -> None:
        """Keep ``settings`` in the project (saved with it; not an undoable edit)."""
        self.project.settings[SETTINGS_KEY] = settings.to_dict()

    # -- frames, views, components -------------------------------------------------------------
    @property
    def frames(self) -> list[int]:
        return list(self.project.frames)

    @property
    def views(self):
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
        """One image (cached); raises InputError naming the file, or saying it is missing."""
        path = self.image_path(frame, view)
        if path is None:
            n = len(self.project.sequences[view].paths) if view < len(self.project.sequences) else 0
            raise InputError(f"view {view + 1}", f"no image for frame {frame} (this camera has {n} images)")
        with self._cache_lock:
            if path in self._images:
                self._images.move_to_end(path)
                return self._images[path]
        views = self.project.views
        image = read_view_image(path, views[view] if view < len(views) else None)
        with self._cache_lock:
            self._images[path] = image
            while len(self._images) > IMAGE_CACHE_FRAMES * max(1, self.n_views):
                self._images.popitem(last=False)
        return image

    def images(self, frame: int) -> list[np.ndarray]:
        """The images of a frame, one per view; raises InputError."""
        return [self.image(frame, v) for v in range(self.n_views)]

    def raw_mesh(self, component: str) -> tuple[np.ndarray, np.ndarray]:
        """Vertices and faces of a component's mesh in its local frame; raises InputError."""
        if component not in self._raw_meshes:
            entry = self.project.model(component)
            if entry is None:
                raise KeyError(component)
            self._raw_meshes[component] = read_model(entry.mesh_path, entry.local_frame)
        return self._raw_meshes[component]

    def relink_mesh(self, component: str, path) -> None:
        """Point a component at another mesh file (its file moved or is missing): the file
        is loaded first (InputError if it cannot be), then the change is one undoable step."""
        entry = self.project.model(component)
        if entry is None:
            raise KeyError(component)
        path = Path(path)
        load_mesh(path)
        self.history.push(Command(f"Locate the {component} model", component, entry.mesh_path, path,
                                  self._store_mesh_path))

    def _store_mesh_path(self, component: str, path: Path) -> None:
        self.project.model(component).mesh_path = Path(path)
        self._raw_meshes.pop(component, None)
        self._meshes.pop(component, None)
        self._notify("model", component)

    def mesh(self, component: str) -> PreparedMesh:
        """The prepared mesh of a component (cached); raises InputError naming the file."""
        if component not in self._meshes:
            self._meshes[component] = prepared_model(self.project.model(component).mesh_path,
                                                     *self.raw_mesh(component))
        return self._meshes[component]

    # -- poses ---------------------------------------------------------------------------------
    def pose_record(self, component: str, frame: int) -> PoseRecord | None:
        return self.project.poses.get((frame, component))

    def pose(self, component: str, frame: int) -> np.ndarray:
        """The component's pose in a frame: its own, else the nearest earlier (then later)
        frame's, else a default placing the model where the two central rays meet."""
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

    def set_pose(self, component: str, frame: int, pose, text: str = "Move model", mergeable: bool = False) -> None:
        """Set a pose by hand (status ``placed``) through the history."""
        self._push_pose(component, frame, PoseRecord(as_pose(pose)), text, "move" if mergeable else None)

    def set_record(self, component: str, frame: int, record: PoseRecord | None, text: str) -> None:
        """Store a whole pose record (a match result) through the history."""
        self._push_pose(component, frame, record, text, None)

    def set_reviewed(self, component: str, frame: int, reviewed: bool = True) -> None:
        """Accept (or reopen) a component's pose in a frame."""
        before = self.project.poses.get((frame, component))
        if before is None:
            after = PoseRecord(self.pose(component, frame), None, reviewed=reviewed)
        else:
            after = PoseRecord(before.pose.copy(), before.match, reviewed=reviewed, status=before.status,
                               reason=before.reason)
        self._push_pose(component, frame, after, "Accept pose" if reviewed else "Reopen pose", None)

    def place_at(self, component: str, frame: int, pixels) -> float:
        """Point-and-click placement: move the model's centroid to where the rays through
        ``pixels`` (one per view) meet, keeping its orientation. Returns the rays' miss (mm)."""
        point, miss = triangulate(self.project.views[:2], [np.asarray(p, float) for p in pixels])
        pose = self.pose(component, frame)
        R = rotation_matrix(*pose[3:])
        pose[:3] = point - R @ self.mesh(component).centroid
        self.set_pose(component, frame, pose, text="Place model")
        return float(miss)

    def orient(self, component: str, frame: int, angles) -> None:
        """Give the model a preset orientation, turning it about its centroid."""
        pose = self.pose(component, frame)
        centroid = self.mesh(component).centroid
        world_centroid = rotation_matrix(*pose[3:]) @ centroid + pose[:3]
        angles = np.asarray(angles, dtype=float)
        pose[3:] = angles
        pose[:3] = world_centroid - rotation_matrix(*angles) @ centroid
        self.set_pose(component, frame, pose, text="Orientation preset")

    def _push_pose(self, component, frame, after, text, merge_id) -> None:
        key = (int(frame), component)
        before = self.project.poses.get(key)
        self.history.push(Command(text, key, before, after, self._store_pose, merge_id))

    def _store_pose(self, key, record: PoseRecord | None) -> None:
        if record is None:
            self.project.poses.pop(key, None)
        else:
            self.project.poses[key] = PoseRecord(record.pose.copy(), record.match, reviewed=record.reviewed,
                                                 status=record.status, reason=record.reason)
        self._notify("pose", key)

    # -- outlines ------------------------------------------------------------------------------
    def outline_record(self, key) -> OutlineRecord | None:
        return self.project.records.get(tuple(key))

    def outline_points(self, key) -> np.ndarray | None:
        record = self.project.records.get(tuple(key))
        return None if record is None else record.points.copy()

    def set_outline(self, key, points, text: str = "Edit outline", reviewed: bool | None = True,
                    weights: np.ndarray | None = None) -> None:
        """Change an outline through the history (None removes it). A user's edit marks the
        outline reviewed (it is then used as it is); ``reviewed=None`` keeps the flag.
        ``weights``: the points' weights in a match (``OutlineRecord.weights``); without
        them an outline whose points stay the same keeps its weights (marking it reviewed
        does not change how it matches), an edited one has none."""
        key = (int(key[0]), int(key[1]), str(key[2]))
        before = self.project.records.get(key)
        if points is None:
            after = None
        else:
            points = np.asarray(points, dtype=float).reshape(-1, 2)
            keep = before.reviewed if (before is not None and reviewed is None) else bool(reviewed)
            if weights is None and before is not None and np.array_equal(before.points, points):
                weights = before.weights
            after = self._new_record(key, points, keep, weights)
        self.history.push(Command(text, key, before, after, self._store_outline))

    def _new_record(self, key, points: np.ndarray, reviewed: bool, weights=None) -> OutlineRecord:
        """The record keeps the points; ``spline`` fits them when first asked (the same
        spline every time, so neither the file nor storing a tracked frame needs it)."""
        return OutlineRecord(points, None, reviewed=reviewed, weights=weights)

    def _store_outline(self, key, record: OutlineRecord | None) -> None:
        if record is None:
            self.project.records.pop(key, None)
        else:
            self.project.records[key] = record
        self._notify("outline", key)

    def spline(self, key) -> OutlineSpline | None:
        """The spline of an outline record (fitted once per record), None if it cannot have one."""
        key = tuple(key)
        record = self.project.records.get(key)
        if record is None or len(record.points) < 4:
            return None
        cached = self._splines.get(key)
        if cached is None or cached[0] is not record:  # e.g. a record loaded from a file
            cached = self._splines[key] = (record, fitted_outline(record.points, record.weights))
        return cached[1]

    def given_splines(self, component: str, frame: int) -> list[OutlineSpline | None] | None:
        """The reviewed outlines of a component per view (None where a view has none, and
        None overall when no view has one): matching uses them as they are."""
        out = []
        for view in range(self.n_views):
            record = self.project.records.get((frame, view, component))
            out.append(self.spline((frame, view, component)) if record is not None and record.reviewed else None)
        return out if any(s is not None for s in out) else None

    # -- results -------------------------------------------------------------------------------
    def store(self, results: FrameResult | Iterable[FrameResult], text: str | None = None) -> None:
        """Put match or tracking results into the project as one undoable step: the pose
        record with its status and reason, and the automatic outlines (never replacing a
        reviewed outline, never touching a pose the user accepted)."""
        results = [results] if isinstance(results, FrameResult) else list(results)
        todo = [r for r in results if not r.kept]
        if not todo:
            return
        label = text or ("Match " + ", ".join(sorted({r.component for r in todo})) +
                         (f" in frame {todo[0].frame}" if len({r.frame for r in todo}) == 1 else ""))
        self.history.begin_macro(label)
        try:
            for r in todo:
                existing = self.project.poses.get((r.frame, r.component))
                if existing is not None and existing.reviewed:
                    continue
                weights = r.outline_weights or []
                for view, points in enumerate(r.outlines or []):
                    key = (r.frame, view, r.component)
                    old = self.project.records.get(key)
                    if points is not None and (old is None or not old.reviewed):
                        # 1e-4 px is far below the edges' accuracy and keeps the file small
                        w = weights[view] if view < len(weights) else None
                        self.set_outline(key, np.round(points, 4), "Automatic outline", reviewed=False,
                                         weights=w)
                record = r.record()
                if record is not None:
                    self.set_record(r.component, r.frame, record, "Match")
        finally:
            self.history.end_macro()

    # -- progress of the work --------------------------------------------------------------------
    def frame_state(self, frame: int) -> FrameState:
        names = self.components()
        if not names:
            return FrameState.EMPTY
        records = [self.project.poses.get((frame, c)) for c in names]
        if any(r is not None and r.needs_review for r in records):
            return FrameState.NEEDS_REVIEW
        if all(r is not None and r.is_matched for r in records):
            return FrameState.REVIEWED if all(r.reviewed for r in records) else FrameState.MATCHED
        if any((frame, v, c) in self.project.records for v in range(self.n_views) for c in names):
            return FrameState.OUTLINED
        return FrameState.EMPTY

    def frame_states(self) -> list[FrameState]:
        return [self.frame_state(f) for f in self.project.frames]
