"""The condylar contact CSV: each condyle's lowest point on the tray (tibial anatomical
frame), its gap to the insert and lift-off, one row per frame (``--contact``; the same
columns as ``fluorogui kinematics --contact``, see ``workflow.contact``)."""
from __future__ import annotations

from fluorogui.core.knee.contact import LIFTOFF_MM
from fluorogui.io.pose_files import read_frame_json
from fluorogui.workflow.exports.registry import ExportFormat, FormatOption, register

#: a lift-off threshold beyond this (mm) is a mistake: condyles are some 20 mm across
MAX_LIFTOFF_MM = 50.0


def liftoff_threshold(text) -> float:
    """A lift-off threshold (mm) above 0 and at most ``MAX_LIFTOFF_MM``; ValueError otherwise."""
    value = float(text)
    if not 0 < value <= MAX_LIFTOFF_MM:  # NaN fails too
        raise ValueError(f"{text} is out of range; give more than 0 and at most {MAX_LIFTOFF_MM:g} mm")
    return value


def _write(session, path, options):
    from fluorogui.workflow.contact import export_contact_csv

    extra = options.extra
    frame = extra.get("insert_frame")
    if frame and not extra.get("insert_mesh"):
        from fluorogui.io.errors import InputError

        raise InputError(frame, "places the insert model: give --insert-mesh too")
    return [export_contact_csv(session, path, insert_mesh=extra.get("insert_mesh"),
                               insert_to_tray=read_frame_json(frame) if frame else None,
                               liftoff_mm=extra.get("liftoff_mm") or LIFTOFF_MM)]


FORMAT = register(ExportFormat(
    name="contact", order=55, label="Condylar contact: lowest points, gaps, lift-off (CSV)",
    default_name="{stem}_contact.csv", metavar="CONTACT.csv",
    help="each condyle's lowest point on the tray (tibial frame), its gap to the insert and lift-off, one row "
         "per frame",
    short="contact CSV", kinematic=True, write=_write,
    options=(FormatOption("--insert-mesh", "insert_mesh", "the insert (polyethylene) model, placed by the tray's "
                                                          "pose: gives the gaps and lift-off by gap", "MESH"),
             FormatOption("--insert-frame", "insert_frame", '{"matrix": [[4 rows of 4]]}, insert model -> tibial '
                                                            "(tray) model; identity by default", "F.json"),
             FormatOption("--liftoff-mm", "liftoff_mm", "a condyle lifts off beyond this gap (without an insert: "
                                                        "this much higher than the other condyle); default 1.0",
                          "MM", liftoff_threshold))))
