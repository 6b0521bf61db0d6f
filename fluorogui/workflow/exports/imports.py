"""Poses from other tools into a session (our CSV, Autoscoper ``.tra``, JointTrack
``.jts``), and the kinematics of bare pose files (no session)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fluorogui.core.knee.kinematics import KneeKinematics, check_side, knee_kinematics
from fluorogui.core.projection.pose import matrix_to_pose, pose_to_matrix
from fluorogui.core.records import PoseRecord
from fluorogui.core.status import Status
from fluorogui.io.errors import InputError
from fluorogui.io.pose_files import jointtrack_to_world_pose, read_jts, read_pose_csv, read_tra
from fluorogui.workflow.session.knee import KNEE_COMPONENTS


def read_poses_file(session, path, component: str | None = None, view: int = 0) -> dict[tuple[int, str], np.ndarray]:
    """Poses by (frame, component) from our CSV (long or wide), an Autoscoper ``.tra``
    (femoral then tibial; rows are the session's frames in order) or a JointTrack ``.jts``
    (``component`` says which; rows are the session's frames, in ``view``'s camera frame)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".jts":
        if component not in KNEE_COMPONENTS:
            raise InputError(path, "say which component a .jts file holds (femoral or tibial)")
        rows = read_jts(path)
        _check_row_count(path, len(rows), session.frames)
        camera = session.views[view]
        return {(f, component): jointtrack_to_world_pose(r, camera)
                for f, r in zip(session.frames, rows) if r is not None}
    if suffix == ".tra":
        components = ([c for c in KNEE_COMPONENTS if session.project.model(c) is not None]
                      if component is None else [component])
        rows = read_tra(path, len(components))
        _check_row_count(path, len(rows), session.frames)
        return {(f, c): matrix_to_pose(m) for f, row in zip(session.frames, rows)
                for c, m in zip(components, row) if m is not None}
    poses = read_pose_csv(path)
    unknown = sorted({f for f, _ in poses} - set(session.frames))
    if unknown:
        raise InputError(path, f"frame {unknown[0]} is not a frame of this session")
    return {k: v for k, v in poses.items() if np.all(np.isfinite(v)) and (component is None or k[1] == component)}


def _check_row_count(path: Path, rows: int, frames: list[int]) -> None:
    if rows != len(frames):
        raise InputError(path, f"has {rows} rows but the session has {len(frames)} frames")


def import_poses(session, path, *, component: str | None = None, view: int = 0, replace: bool = False,
                 kept: list | None = None) -> int:
    """Read poses from another tool into the session (status ``placed``, reason naming the
    file, so they are reviewed before use) as one undoable step; returns how many. Poses
    matched or accepted in the session are kept (their (frame, component) appended to
    ``kept``) unless ``replace``."""
    poses = read_poses_file(session, path, component, view)
    if not replace:
        for frame, c in sorted(poses):
            if c in session.matched_in(frame, c):
                del poses[(frame, c)]
                if kept is not None:
                    kept.append((frame, c))
    name = Path(path).name
    session.history.begin_macro(f"Import poses from {name}")
    try:
        for (frame, c), pose in sorted(poses.items()):
            session.set_record(c, frame, PoseRecord(pose, status=Status.PLACED, reason=f"imported from {name}"),
                               f"Import {c} pose")
    finally:
        session.history.end_macro()
    return len(poses)


def kinematics_of_poses(poses: dict[tuple[int, str], np.ndarray], side: str, femoral_frame, tibial_frame
                        ) -> list[tuple[int, KneeKinematics, str]]:
    """Kinematics per frame of bare poses; NaN with a reason where a component is missing."""
    side = check_side(side)
    out = []
    for frame in sorted({f for f, _ in poses}):
        pose = {c: poses.get((frame, c)) for c in KNEE_COMPONENTS}
        lacking = [c for c in KNEE_COMPONENTS if pose[c] is None or not np.all(np.isfinite(pose[c]))]
        if lacking:
            reason = " and ".join(f"{c} pose {'missing' if pose[c] is None else 'is NaN'}" for c in lacking)
            out.append((frame, KneeKinematics.missing(), reason))
            continue
        values = knee_kinematics(pose_to_matrix(pose["femoral"]), pose_to_matrix(pose["tibial"]),
                                 femoral_frame, tibial_frame, side=side)
        out.append((frame, values, ""))
    return out
