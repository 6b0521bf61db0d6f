"""The knee of a session: its side, each component's anatomical frame and the joint
kinematics frame by frame, from the stored poses. Qt-free; the app, the command line and
scripts all read kinematics from here. ``Knee`` is a part of ``Session``: it is given the
project, the history, the cache (the default frames), the reader (frames, meshes) and
``notify``.

Kept in ``project.settings["kinematics"]``::

    {"side": "right" | "left" | null,
     "frames": {"femoral": {"matrix": [[4 rows of 4]], "source": "user"}, ...}}

A component without a stored frame uses the default from its mesh
(``fluorogui.core.knee.anatomy``), computed when first needed and not written into the project
until the user sets one.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from fluorogui.core.knee.anatomy import default_frame
from fluorogui.core.knee.kinematics import (
    KinematicsError,
    KneeKinematics,
    check_frame,
    check_side,
    kinematics_sd,
    kinematics_sd_body,
    knee_kinematics,
)
from fluorogui.core.projection.pose import pose_to_matrix
from fluorogui.core.records import PoseRecord, Project
from fluorogui.core.status import Status
from fluorogui.workflow.session.cache import SessionCache
from fluorogui.workflow.session.events import SessionEvent
from fluorogui.workflow.session.history import Command, CommandStack
from fluorogui.workflow.session.reader import Reader

KNEE_KEY = "kinematics"
KNEE_COMPONENTS = ("femoral", "tibial")


@dataclass
class KneeRow:
    """One frame's kinematics with what it rests on (:meth:`Session.knee_rows`).

    Attributes
    ----------
    frame : int
    values : fluorogui.core.knee.kinematics.KneeKinematics
        Flexion, varus, internal rotation (degrees), medial, anterior and distraction
        translations (mm); NaN when ``status`` is ``missing``.
    status : str
        ``matched`` (both poses passed their checks), ``needs_review`` (one did not, or was
        placed by hand) or ``missing`` (a pose is absent or failed).
    reason : str
        Why, when not ``matched``.
    records : dict
        Component name to its :class:`~fluorogui.core.records.PoseRecord` (or None).
    sd : numpy.ndarray
        The six values' standard deviations, propagated from the poses' SDs (NaN where a
        match gave none).
    """

    frame: int
    values: KneeKinematics
    status: str  # "matched", "needs_review" or "missing"
    reason: str = ""
    records: dict = field(default_factory=dict)  # component -> PoseRecord or None
    sd: np.ndarray = field(default_factory=lambda: np.full(6, np.nan))  # of the six values, from the matches


def record_sd(record: PoseRecord | None) -> np.ndarray:
    """The six pose SDs a match reported (mm, degrees), NaN where it reported none."""
    if record is None or record.match is None or not isinstance(record.match.quality, dict):
        return np.full(6, np.nan)
    sd = record.match.quality.get("sd")  # where the matcher keeps it (``core.matching.problem.MatchResult.sd``)
    try:
        sd = np.asarray(sd, dtype=float).reshape(6)
    except (TypeError, ValueError):
        return np.full(6, np.nan)
    return sd


def record_body_uncertainty(record: PoseRecord | None) -> np.ndarray | None:
    """The uncertainty of a match's body motion (centroid world mm, turn about the model's
    axes deg): its 6x6 covariance where the match kept it, else its six SDs; None where it
    kept neither (an older project, a pose placed by hand) or they are not all finite."""
    if record is None or record.match is None or not isinstance(record.match.quality, dict):
        return None
    for key, size in (("cov_body", 36), ("sd_body", 6)):
        value = record.match.quality.get(key)
        if value is None:
            continue
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            continue
        if array.size == size and np.all(np.isfinite(array)):
            return array.reshape(6, 6) if size == 36 else array.reshape(6)
    return None


def row_status(records: dict) -> tuple[str, str]:
    """The status and reason of a frame's kinematics from its two pose records."""
    missing = [c for c in KNEE_COMPONENTS if records.get(c) is None]
    if missing:
        return "missing", f"no {' or '.join(missing)} pose"
    failed = [c for c in KNEE_COMPONENTS if records[c].status == Status.FAILED]
    if failed:
        return "missing", f"the {' and '.join(failed)} match failed"
    reasons = []
    for c in KNEE_COMPONENTS:
        record: PoseRecord = records[c]
        if record.status == Status.NEEDS_REVIEW and not record.reviewed:
            reasons.append(f"{c} needs review" + (f" ({record.reason})" if record.reason else ""))
        elif record.status == Status.PLACED and not record.reviewed:
            reasons.append(f"{c} placed by hand, not matched")
    if reasons:
        return "needs_review", "; ".join(reasons)
    return Status.MATCHED, ""


class Knee:
    """The knee's side, anatomical frames and kinematics of a session.

    Parameters
    ----------
    project : fluorogui.core.records.Project
        Its ``settings["kinematics"]`` and poses.
    history : CommandStack
        Where a change of side or frame goes, as one ``Command``.
    cache : SessionCache
        Its ``anatomical_frames``: the default frame found on each mesh.
    reader : Reader
        The frame numbers and the meshes.
    notify : callable
        ``notify(event, what)`` after every change (``SessionEvent.KNEE``).
    """

    def __init__(self, *, project: Project, history: CommandStack, cache: SessionCache, reader: Reader,
                 notify: Callable[[str, object], None]) -> None:
        self.project = project
        self.history = history
        self.cache = cache
        self.reader = reader
        self.notify = notify

    def _knee(self, create: bool = False) -> dict:
        """The knee's settings (made in the project only when ``create``, for a change)."""
        knee = self.project.settings.get(KNEE_KEY)
        if not isinstance(knee, dict):
            knee = {}
            if create:
                self.project.settings[KNEE_KEY] = knee
        return knee

    # -- side -------------------------------------------------------------------------------
    @property
    def side(self) -> str | None:
        """The knee's side: ``"right"``, ``"left"``, or None when nobody said (kinematics are
        then computed as a right knee)."""
        value = self._knee().get("side")
        return value if value in ("right", "left") else None

    def set_side(self, side: str) -> None:
        """Set the knee's side, as one undoable edit; it sets the signs of the kinematics.

        Parameters
        ----------
        side : {"right", "left"}

        Raises
        ------
        fluorogui.core.knee.kinematics.KinematicsError
            Neither right nor left.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.side is None
        True
        >>> session.set_side("left")
        >>> session.side
        'left'
        """
        self._push_knee("side", check_side(side), "Set knee side")

    def _push_knee(self, key: str, after, text: str) -> None:
        knee = self._knee()
        before = knee.get(key) if key == "side" else knee.get("frames", {}).get(key)
        self.history.push(Command(text, key, before, after, self._store_knee))

    def _store_knee(self, key: str, value) -> None:
        knee = self._knee(create=True)
        if key == "side":
            knee["side"] = value
        elif value is None:
            knee.get("frames", {}).pop(key, None)
        else:
            knee.setdefault("frames", {})[key] = value
        self.notify(SessionEvent.KNEE, key)

    # -- anatomical frames ----------------------------------------------------------------------
    def anatomical_frame(self, component: str) -> np.ndarray:
        """The component's anatomical frame: the one a user set, else the default from its mesh.

        Parameters
        ----------
        component : {"femoral", "tibial"}

        Returns
        -------
        numpy.ndarray
            4×4 rigid transform, anatomical → model coordinates (x to the subject's right,
            y anterior, z proximal, origin at the joint centre).

        Raises
        ------
        fluorogui.core.knee.kinematics.KinematicsError
            No default frame can be found on the mesh.
        fluorogui.io.errors.InputError
            The mesh cannot be read.
        """
        stored = self._knee().get("frames", {}).get(component)
        if isinstance(stored, dict) and "matrix" in stored:
            try:
                return check_frame(stored["matrix"])
            except KinematicsError:
                pass  # a broken stored frame falls back to the default, as if never set
        return self.default_anatomical_frame(component)

    def default_anatomical_frame(self, component: str) -> np.ndarray:
        """The frame ``fluorogui.core.knee.anatomy`` finds on the component's mesh (cached)."""
        cache = self.cache.anatomical_frames
        if component not in cache:
            vertices, faces = self.reader.raw_mesh(component)
            cache[component] = default_frame(component, vertices, faces)
        return cache[component].copy()

    def anatomical_frame_source(self, component: str) -> str:
        stored = self._knee().get("frames", {}).get(component)
        return "user" if isinstance(stored, dict) and "matrix" in stored else "default"

    def set_anatomical_frame(self, component: str, matrix) -> None:
        """Keep a user's anatomical frame in the project, as one undoable edit.

        Parameters
        ----------
        component : {"femoral", "tibial"}
        matrix : array_like of shape (4, 4)
            Anatomical → model coordinates.

        Raises
        ------
        fluorogui.core.knee.kinematics.KinematicsError
            The matrix is not a rigid transform (orthonormal, determinant +1, bottom row
            0 0 0 1) within 1e-6.
        """
        matrix = check_frame(matrix)
        self._push_knee(component, {"matrix": matrix.tolist(), "source": "user"},
                        f"Set {component} anatomical frame")

    def reset_anatomical_frame(self, component: str) -> None:
        """Go back to the default frame from the mesh (an undoable edit)."""
        self._push_knee(component, None, f"Default {component} anatomical frame")

    # -- kinematics ----------------------------------------------------------------------------
    def knee_rows(self, frames=None) -> list[KneeRow]:
        """The knee's kinematics frame by frame (Grood & Suntay), from the stored poses.

        Parameters
        ----------
        frames : iterable of int, optional
            Frame numbers; all by default.

        Returns
        -------
        list of KneeRow
            One per frame; NaN values with a reason where a component has no pose.

        Examples
        --------
        >>> from fluorogui import Session
        >>> from fluorogui.simulation.demo import demo_project_path
        >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
        >>> session.set_pose("femoral", 1, [1.53, 7.51, 20.53, 28.03, 1.2, -1.58])
        >>> session.set_pose("tibial", 1, [0.8, 1.0, -20.0, -12.02, 0.73, 3.42])
        >>> row = session.knee_rows([1])[0]
        >>> row.status
        'needs_review'
        >>> round(row.values.flexion_deg, 1)
        40.0
        """
        side = self.side or "right"
        absent = [c for c in KNEE_COMPONENTS if self.project.model(c) is None]
        anat = {c: self.anatomical_frame(c) for c in KNEE_COMPONENTS if c not in absent}
        rows = []
        for frame in (self.reader.frames if frames is None else frames):
            records = {c: self.project.poses.get((frame, c)) for c in KNEE_COMPONENTS}
            status, reason = row_status(records)
            if absent:  # a one-component session: poses export, kinematics are NaN
                status, reason = "missing", f"no {' or '.join(absent)} model in this session"
            sd = np.full(6, np.nan)
            if status == "missing":
                values = KneeKinematics.missing()
            else:
                femur, tibia = records["femoral"].pose, records["tibial"].pose
                values = knee_kinematics(pose_to_matrix(femur), pose_to_matrix(tibia), anat["femoral"], anat["tibial"],
                                         side=side)
                sd = self._sd(records, anat, side)
            rows.append(KneeRow(frame, values, status, reason, records, sd))
        return rows

    def _sd(self, records: dict, anat: dict, side: str) -> np.ndarray:
        """The six values' SDs: from the body's own uncertainty where both matches kept it
        (its whole covariance when kept), else from the Euler angles' SDs as independent,
        which near gimbal lock overstates them (the real femur, gamma ~78 deg: its alpha and
        beta SDs are ~1 deg, its turns 0.07-0.21 deg)."""
        femur, tibia = records["femoral"].pose, records["tibial"].pose
        body = [record_body_uncertainty(records[c]) for c in KNEE_COMPONENTS]
        if all(b is not None for b in body):
            centroids = [self.reader.mesh(c).centroid for c in KNEE_COMPONENTS]
            return kinematics_sd_body(pose_to_matrix(femur), pose_to_matrix(tibia), anat["femoral"], anat["tibial"],
                                      side=side, femoral_cov=body[0], tibial_cov=body[1],
                                      femoral_centroid=centroids[0], tibial_centroid=centroids[1])
        return kinematics_sd(femur, tibia, anat["femoral"], anat["tibial"], side=side,
                             femoral_sd=record_sd(records["femoral"]), tibial_sd=record_sd(records["tibial"]),
                             pose_matrix=pose_to_matrix)

    def knee_at(self, frame: int) -> KneeRow:
        return self.knee_rows([frame])[0]


__all__ = ["KNEE_COMPONENTS", "KNEE_KEY", "Knee", "KneeRow", "record_sd", "row_status"]
