"""Contact kinematics of a session or of bare poses, frame by frame: each condyle's lowest
point on the tray, its gap to an insert, lift-off, then the pivot of axial rotation and
the rollback over the activity (definitions: ``fluorogui.core.knee.contact``). Qt-free;
the command line and the exports call these.

A frame gets values when both poses are there and not failed, with the kinematics row's
status (``matched`` or ``needs_review``, with its reason); otherwise NaN values and
``missing``. The pivot and the rollback use matched frames only.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fluorogui import __version__
from fluorogui.core.knee.contact import (
    CONTACT_SIGN_CONVENTIONS,
    LIFTOFF_MM,
    Contact,
    FemoralSurface,
    Insert,
    Pivot,
    Rollback,
    condyle_contact,
    pivot,
    place_insert,
    prepare_femur,
    rollback,
)
from fluorogui.core.knee.kinematics import SIGN_CONVENTIONS, check_side, knee_kinematics
from fluorogui.core.projection.pose import pose_to_matrix
from fluorogui.core.status import Status
from fluorogui.io.files import check_output_file
from fluorogui.io.meshes.model import read_model
from fluorogui.io.pose_files import write_csv

CONTACT_COLUMNS = ("frame", "medial_x_mm", "medial_y_mm", "medial_z_mm", "lateral_x_mm", "lateral_y_mm",
                   "lateral_z_mm", "medial_gap_mm", "lateral_gap_mm", "liftoff", "status")


@dataclass(frozen=True)
class ContactSetup:
    """What contact kinematics needs besides the poses.

    Attributes
    ----------
    femur : fluorogui.core.knee.contact.FemoralSurface
    tibial_frame : numpy.ndarray
        The tibial anatomical frame (4×4, anatomical → model).
    side : str
    insert : fluorogui.core.knee.contact.Insert or None
    liftoff_mm : float
    insert_source : str
        Where the insert came from, for the file headers ("" without one).
    """

    femur: FemoralSurface
    tibial_frame: np.ndarray
    side: str
    insert: Insert | None = None
    liftoff_mm: float = LIFTOFF_MM
    insert_source: str = ""


def contact_setup(femoral_mesh, *, femoral_frame, tibial_frame, side: str, insert_mesh=None,
                  insert_to_tray=None, liftoff_mm: float = LIFTOFF_MM) -> ContactSetup:
    """A setup from the femoral mesh ``(vertices, faces)``, the anatomical frames, and
    optionally an insert: a mesh file or ``(vertices, faces)`` with its insert → tray
    (tibial model) matrix, identity by default.

    Raises
    ------
    fluorogui.io.errors.InputError
        The insert mesh file cannot be read.
    ValueError
        ``liftoff_mm`` is not a positive number.
    """
    if not (np.isfinite(liftoff_mm) and liftoff_mm > 0):
        raise ValueError(f"the lift-off threshold must be a positive number of mm, not {liftoff_mm!r}")
    femur = prepare_femur(*femoral_mesh, femoral_frame)
    insert, source = None, ""
    if insert_mesh is not None:
        if isinstance(insert_mesh, (str, Path)):
            source = Path(insert_mesh).name
            insert_mesh = read_model(insert_mesh)
        else:
            source = "given mesh"
        matrix = np.eye(4) if insert_to_tray is None else np.asarray(insert_to_tray, dtype=float)
        insert = place_insert(*insert_mesh, tibial_frame, matrix)
        source += f" (insert -> tray: {np.round(matrix, 9).tolist()})"
    return ContactSetup(femur, np.asarray(tibial_frame, dtype=float), check_side(side), insert, float(liftoff_mm),
                        source)


def session_contact_setup(session, *, insert_mesh=None, insert_to_tray=None,
                          liftoff_mm: float = LIFTOFF_MM) -> ContactSetup:
    """The setup of a session: its femoral mesh, anatomical frames and side (right when
    not set)."""
    return contact_setup(session.raw_mesh("femoral"), femoral_frame=session.anatomical_frame("femoral"),
                         tibial_frame=session.anatomical_frame("tibial"), side=session.side or "right",
                         insert_mesh=insert_mesh, insert_to_tray=insert_to_tray, liftoff_mm=liftoff_mm)


@dataclass
class ContactRow:
    """One frame's contact (:func:`contact_rows`).

    Attributes
    ----------
    frame : int
    contact : fluorogui.core.knee.contact.Contact
        NaN points when ``status`` is ``missing``.
    status : str
        ``matched``, ``needs_review`` or ``missing``, as the frame's kinematics row.
    reason : str
    flexion_deg : float
        The frame's flexion (Grood & Suntay), for plots against flexion.
    """

    frame: int
    contact: Contact
    status: str
    reason: str = ""
    flexion_deg: float = float("nan")


def _row(frame: int, status: str, reason: str, poses, *, setup: ContactSetup, flexion: float) -> ContactRow:
    if status == "missing":
        return ContactRow(frame, Contact.missing(), status, reason, flexion)
    contact = condyle_contact(setup.femur, pose_to_matrix(poses[0]), pose_to_matrix(poses[1]),
                              tibial_frame=setup.tibial_frame, side=setup.side, insert=setup.insert,
                              liftoff_mm=setup.liftoff_mm)
    return ContactRow(frame, contact, status, reason, flexion)


def contact_rows(session, setup: ContactSetup | None = None, frames=None, knee_rows=None) -> list[ContactRow]:
    """Contact per frame of a session, from its stored poses.

    Parameters
    ----------
    session : fluorogui.workflow.session.Session
    setup : ContactSetup, optional
        By default :func:`session_contact_setup` without an insert.
    frames : iterable of int, optional
        All by default.
    knee_rows : list of KneeRow, optional
        The session's ``knee_rows(frames)`` when the caller has them already.
    """
    setup = session_contact_setup(session) if setup is None else setup
    rows = session.knee_rows(frames) if knee_rows is None else knee_rows
    out = []
    for row in rows:
        poses = None
        if row.status != "missing":
            poses = (row.records["femoral"].pose, row.records["tibial"].pose)
        out.append(_row(row.frame, row.status, row.reason, poses, setup=setup, flexion=float(row.values.flexion_deg)))
    return out


def session_contact_job(session, knee_rows=None):
    """What :func:`contact_rows` needs of a session, taken now (its femoral mesh, anatomical
    frames, side and ``knee_rows``), and a callable that computes from it, later and in
    another thread if wished (it no longer reads the session): ``() -> (rows, pivot)``.

    Raises
    ------
    KeyError, fluorogui.io.errors.InputError, fluorogui.core.knee.kinematics.KinematicsError
        A model is missing or unreadable.
    """
    mesh = session.raw_mesh("femoral")
    frames = {c: session.anatomical_frame(c) for c in ("femoral", "tibial")}
    side = session.side or "right"
    rows = session.knee_rows() if knee_rows is None else list(knee_rows)

    def run() -> tuple[list[ContactRow], Pivot]:
        setup = contact_setup(mesh, femoral_frame=frames["femoral"], tibial_frame=frames["tibial"], side=side)
        out = contact_rows(None, setup, knee_rows=rows)
        return out, pivot_of_rows(out)

    return run


def contact_world_points(row: ContactRow, tibial_pose, tibial_frame, side: str) -> dict[str, np.ndarray]:
    """A row's lowest points in world mm (``{"medial": (3,), "lateral": (3,)}``, NaN when
    missing): undone the left knee's mirror, through the tibial anatomical frame
    (anatomical → model) and the tray's pose (model → world, a 6-vector or 4×4)."""
    pose = np.asarray(tibial_pose, dtype=float)
    to_world = (pose if pose.shape == (4, 4) else pose_to_matrix(pose)) @ np.asarray(tibial_frame, dtype=float)
    mirror = np.array([1.0 if check_side(side) == "right" else -1.0, 1.0, 1.0])
    return {name: to_world[:3, :3] @ (getattr(row.contact, name).lowest * mirror) + to_world[:3, 3]
            for name in ("medial", "lateral")}


def contact_of_poses(poses: dict[tuple[int, str], np.ndarray], setup: ContactSetup, femoral_frame
                     ) -> list[ContactRow]:
    """Contact per frame of bare poses (``{(frame, component): pose}``). A frame with both
    poses is taken as matched (a pose file carries no checks); one lacking a pose is
    missing."""
    out = []
    for frame in sorted({f for f, _ in poses}):
        pose = [poses.get((frame, c)) for c in ("femoral", "tibial")]
        lacking = [c for c, p in zip(("femoral", "tibial"), pose) if p is None or not np.all(np.isfinite(p))]
        if lacking:
            reason = " and ".join(f"{c} pose {'missing' if p is None else 'is NaN'}"
                                  for c, p in zip(("femoral", "tibial"), pose) if c in lacking)
            out.append(_row(frame, "missing", reason, None, setup=setup, flexion=float("nan")))
            continue
        flexion = knee_kinematics(pose_to_matrix(pose[0]), pose_to_matrix(pose[1]), femoral_frame,
                                  setup.tibial_frame, side=setup.side).flexion_deg
        out.append(_row(frame, Status.MATCHED, "", pose, setup=setup, flexion=float(flexion)))
    return out


def trusted(rows: list[ContactRow]) -> list[ContactRow]:
    """The rows the summaries rest on: matched frames."""
    return [r for r in rows if r.status == Status.MATCHED]


def pivot_of_rows(rows: list[ContactRow]) -> Pivot:
    """The pivot of axial rotation over the matched frames; frames needing review or
    missing are counted as ignored."""
    good = trusted(rows)
    found = pivot([r.contact.medial.lowest[:2] for r in good] or np.empty((0, 2)),
                  [r.contact.lateral.lowest[:2] for r in good] or np.empty((0, 2)))
    return Pivot(found.x_mm, found.y_mm, found.kind, found.frames_used,
                 found.frames_ignored + len(rows) - len(good), found.reason)


def pivot_json(found: Pivot) -> dict:
    """The ``--pivot`` line: ``{"x_mm", "y_mm", "kind", "frames_used"}`` (null when not determined)."""
    def number(v):
        return round(float(v), 4) if np.isfinite(v) else None

    return {"x_mm": number(found.x_mm), "y_mm": number(found.y_mm), "kind": found.kind,
            "frames_used": int(found.frames_used)}


def rollback_of_rows(rows: list[ContactRow]) -> dict[str, Rollback]:
    """Each condyle's rollback (AP against flexion) over the matched frames."""
    good = trusted(rows)
    flexion = [r.flexion_deg for r in good]
    return {name: rollback(flexion, [getattr(r.contact, name).lowest[1] for r in good])
            for name in ("medial", "lateral")}


def contact_cells(rows: list[ContactRow], with_insert: bool) -> list[list]:
    """The CSV's rows: NaN points for missing frames; gaps empty without an insert."""
    out = []
    for r in rows:
        c = r.contact
        gaps = [float(c.medial.gap_mm), float(c.lateral.gap_mm)] if with_insert else ["", ""]
        out.append([r.frame, *(float(v) for v in c.medial.lowest), *(float(v) for v in c.lateral.lowest), *gaps,
                    c.liftoff, r.status])
    return out


def contact_header(setup: ContactSetup, rows: list[ContactRow], source: str) -> list[str]:
    """The ``#`` lines of a contact CSV: version, source, side, conventions, the insert,
    the threshold, the pivot and the rollback, and why frames have no values."""
    found = pivot_of_rows(rows)
    lines = [f"fluorogui {__version__} contact kinematics of {source}",
             f"side: {setup.side}", "units: mm and degrees", f"contact: {CONTACT_SIGN_CONVENTIONS}",
             f"kinematics (flexion): {SIGN_CONVENTIONS}",
             f"insert: {setup.insert_source or 'none (gaps empty; lift-off from the condyles heights)'}",
             f"lift-off threshold: {setup.liftoff_mm:g} mm",
             "status: matched = both poses passed their checks; needs_review = a pose failed a check or was placed "
             "by hand; missing = a pose is absent or failed (values NaN)"]
    if np.isfinite(found.x_mm):
        lines.append(f"pivot: x {found.x_mm:.2f} mm, y {found.y_mm:.2f} mm, {found.kind}; "
                     f"{found.frames_used} frames used, {found.frames_ignored} ignored")
    else:
        lines.append(f"pivot: not determined ({found.reason}); {found.frames_ignored} frames ignored")
    for name, back in rollback_of_rows(rows).items():
        if np.isfinite(back.excursion_mm):
            lines.append(f"{name} condyle: AP {back.ap_at_min_mm:.2f} mm at {back.flexion_min_deg:.1f} deg flexion, "
                         f"{back.ap_at_max_mm:.2f} mm at {back.flexion_max_deg:.1f} deg: rollback "
                         f"{back.excursion_mm:+.2f} mm (+ posterior), AP range {back.range_mm:.2f} mm")
    lines += [f"frame {r.frame}: NaN: {r.reason}" for r in rows if r.status == "missing"]
    return lines


def write_contact_csv(path, setup: ContactSetup, rows: list[ContactRow], source: str) -> Path:
    """Write ``CONTACT_COLUMNS`` per frame, atomically, with :func:`contact_header`."""
    path = check_output_file(path)
    write_csv(path, contact_header(setup, rows, source), list(CONTACT_COLUMNS),
              contact_cells(rows, setup.insert is not None))
    return path


def export_contact_csv(session, path, *, insert_mesh=None, insert_to_tray=None, liftoff_mm: float = LIFTOFF_MM,
                       rows: list[ContactRow] | None = None) -> Path:
    """A session's contact CSV (the export of ``fluorogui export PROJECT --contact``).

    ``rows``: the session's :func:`contact_rows` when the caller has them (then made with
    the same insert and threshold).
    """
    path = check_output_file(path)
    setup = session_contact_setup(session, insert_mesh=insert_mesh, insert_to_tray=insert_to_tray,
                                  liftoff_mm=liftoff_mm)
    rows = contact_rows(session, setup) if rows is None else rows
    name = session.path.name if session.path else "(unsaved project)"
    return write_contact_csv(path, setup, rows, f"project {name}")
