"""The knee of a session: its side, each component's anatomical frame and the joint
kinematics frame by frame, from the stored poses. Qt-free; the app, the command line and
scripts all read kinematics from here.

Kept in ``project.settings["kinematics"]``::

    {"side": "right" | "left" | null,
     "frames": {"femoral": {"matrix": [[4 rows of 4]], "source": "user"}, ...}}

A component without a stored frame uses the default from its mesh
(``fluorogui.core.knee.anatomy``), computed when first needed and not written into the project
until the user sets one.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fluorogui.core.knee.anatomy import default_frame
from fluorogui.core.knee.kinematics import (
    KinematicsError,
    KneeKinematics,
    check_frame,
    check_side,
    kinematics_sd,
    knee_kinematics,
)
from fluorogui.core.projection.pose import pose_to_matrix
from fluorogui.core.records import PoseRecord
from fluorogui.core.status import Status
from fluorogui.workflow.history import Command

KNEE_KEY = "kinematics"
KNEE_COMPONENTS = ("femoral", "tibial")


@dataclass
class KneeRow:
    """One frame's kinematics with what it rests on."""

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
    sd = record.match.quality.get("sd")  # where the matcher keeps it (``core.matching.MatchResult.sd``)
    try:
        sd = np.asarray(sd, dtype=float).reshape(6)
    except (TypeError, ValueError):
        return np.full(6, np.nan)
    return sd


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


class KneeMixin:
    """Kinematics methods of ``Session`` (a mixin; needs ``project`` and ``raw_mesh``)."""

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
        """``right``, ``left``, or None when nobody said (kinematics then assume right)."""
        value = self._knee().get("side")
        return value if value in ("right", "left") else None

    def set_side(self, side: str) -> None:
        """Set the knee's side (an undoable edit)."""
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
        self._notify("knee", key)

    # -- anatomical frames ----------------------------------------------------------------------
    def anatomical_frame(self, component: str) -> np.ndarray:
        """The component's anatomical frame (4×4, anatomical → model): stored, else default."""
        stored = self._knee().get("frames", {}).get(component)
        if isinstance(stored, dict) and "matrix" in stored:
            try:
                return check_frame(stored["matrix"])
            except KinematicsError:
                pass  # a broken stored frame falls back to the default, as if never set
        return self.default_anatomical_frame(component)

    def default_anatomical_frame(self, component: str) -> np.ndarray:
        """The frame ``fluorogui.core.knee.anatomy`` finds on the component's mesh (cached)."""
        cache = self.__dict__.setdefault("_default_frames", {})
        if component not in cache:
            vertices, faces = self.raw_mesh(component)
            cache[component] = default_frame(component, vertices, faces)
        return cache[component].copy()

    def anatomical_frame_source(self, component: str) -> str:
        stored = self._knee().get("frames", {}).get(component)
        return "user" if isinstance(stored, dict) and "matrix" in stored else "default"

    def set_anatomical_frame(self, component: str, matrix) -> None:
        """Keep a user's frame (checked: rigid, det +1) in the project (an undoable edit)."""
        matrix = check_frame(matrix)
        self._push_knee(component, {"matrix": matrix.tolist(), "source": "user"},
                        f"Set {component} anatomical frame")

    def reset_anatomical_frame(self, component: str) -> None:
        """Go back to the default frame from the mesh (an undoable edit)."""
        self._push_knee(component, None, f"Default {component} anatomical frame")

    # -- kinematics ----------------------------------------------------------------------------
    def knee_rows(self, frames=None) -> list[KneeRow]:
        """Kinematics of every frame (NaN with a reason where a component has no pose)."""
        side = self.side or "right"
        absent = [c for c in KNEE_COMPONENTS if self.project.model(c) is None]
        anat = {c: self.anatomical_frame(c) for c in KNEE_COMPONENTS if c not in absent}
        rows = []
        for frame in (self.frames if frames is None else frames):
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
                                         side)
                sd = kinematics_sd(femur, tibia, anat["femoral"], anat["tibial"], side,
                                   record_sd(records["femoral"]), record_sd(records["tibial"]), pose_to_matrix)
            rows.append(KneeRow(frame, values, status, reason, records, sd))
        return rows

    def knee_at(self, frame: int) -> KneeRow:
        return self.knee_rows([frame])[0]


__all__ = ["KNEE_COMPONENTS", "KNEE_KEY", "KneeMixin", "KneeRow", "row_status"]
