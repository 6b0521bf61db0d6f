"""What a fluoroscope's calibration and an implant model's local frame can plausibly be.

A calibration file can hold numbers that describe a valid projection and still no
fluoroscope: an image 10^12 px wide, a focal length of 10^-12 px, a source 10^300 mm away.
Such a file used to pass and fail later, against an image, with a message about the image.
``view_problem`` finds the first implausible quantity of a ``View`` and returns which one
(``SIZE``, ``FOCAL``, ``PITCH``, ``DISTANCE``, ``PRINCIPAL``, ``SOURCE``) and a sentence
with the value and the plausible range; each reader names the field of its own format
(``views[0].distance_mm``, ``section 'camera matrix' (fx, fy)``, ``line 2``, ...).

The ranges are wide (a research rig, a high-speed camera, a synthetic test view pass): an
image 8 to 32,768 px a side, a field of view across it of 0.1 to 120 degrees, a pixel
pitch of 0.001 to 10 mm, a source-intensifier distance of 50 mm to 50 m (formats without a
pixel pitch get an assumed one, so their distance in mm is only nominal), a principal
point at most one image size outside the image, a source within 10 m of the world origin.

``rigid_problem`` does the same for a 4x4 local frame: a rotation (orthonormal, not a
reflection), a translation, and a bottom row of 0, 0, 0, 1.
"""
from __future__ import annotations

import math

import numpy as np

IMAGE_SIDE_PX = (8, 32_768)
FIELD_OF_VIEW_DEG = (0.1, 120.0)
PITCH_MM = (0.001, 10.0)
DISTANCE_MM = (50.0, 50_000.0)
SOURCE_FROM_ORIGIN_MM = 10_000.0
TRANSLATION_MM = 1e7  # a local frame's translation, as any coordinate of a project

SIZE, FOCAL, PITCH, DISTANCE, PRINCIPAL, SOURCE = "size", "focal", "pitch", "distance", "principal", "source"


def view_problem(view) -> tuple[str, str] | None:
    """The first implausible quantity of ``view`` as ``(kind, sentence)``, or None. A view
    whose format has no pixel pitch (``view.extra["pitch_assumed"]``) is judged in pixels
    only: its pitch and distance in mm are nominal."""
    width, height = view.image_size
    lo, hi = IMAGE_SIDE_PX
    if not (lo <= width <= hi and lo <= height <= hi):
        return SIZE, f"image size {width}x{height} px is not plausible for a fluoroscope ({lo} to {hi:,} px a side)"
    if not view.extra.get("pitch_assumed"):
        for pitch in view.pitch:
            if not PITCH_MM[0] <= pitch <= PITCH_MM[1]:
                return PITCH, (f"pixel pitch {pitch:.4g} mm is not plausible for a fluoroscope "
                               f"({PITCH_MM[0]:g} to {PITCH_MM[1]:g} mm)")
        if not DISTANCE_MM[0] <= view.distance <= DISTANCE_MM[1]:
            return DISTANCE, (f"source-intensifier distance {view.distance:.4g} mm is not plausible for a "
                              f"fluoroscope ({DISTANCE_MM[0]:g} mm to {DISTANCE_MM[1] / 1000:g} m)")
    for axis, focal, side in (("fx", view.focal_px[0], width), ("fy", view.focal_px[1], height)):
        fov = 2.0 * math.degrees(math.atan2(side / 2.0, focal)) if focal > 0 else 180.0
        if not FIELD_OF_VIEW_DEG[0] <= fov <= FIELD_OF_VIEW_DEG[1]:
            return FOCAL, (f"focal length {axis} = {focal:.4g} px gives a {fov:.3g}° field of view across "
                           f"{side} px; a fluoroscope's is {FIELD_OF_VIEW_DEG[0]:g}° to {FIELD_OF_VIEW_DEG[1]:g}°")
    cx, cy = view.principal_point
    if not (-width <= cx <= 2 * width and -height <= cy <= 2 * height):
        return PRINCIPAL, (f"principal point ({cx:.4g}, {cy:.4g}) px lies more than an image size outside "
                           f"the {width}x{height} px image")
    largest = float(np.max(np.abs(view.source)))
    distance = largest * float(np.linalg.norm(view.source / largest)) if largest > 0 else 0.0  # no overflow
    if distance > SOURCE_FROM_ORIGIN_MM:
        return SOURCE, (f"the X-ray source lies {distance:.4g} mm from the origin; a fluoroscope's calibration "
                        f"puts it within {SOURCE_FROM_ORIGIN_MM / 1000:g} m")
    return None


def rigid_problem(matrix) -> str | None:
    """Why a 4x4 ``matrix`` is not a rigid transform (``"scale 1000"``, ``"a reflection"``,
    ``"bottom row 5, 5, 5, 5"``), or None when it is one (to 1e-6)."""
    m = np.asarray(matrix, dtype=float)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        return "not a 4x4 matrix of finite numbers"
    scales = np.linalg.svd(m[:3, :3], compute_uv=False)
    if np.max(np.abs(scales - 1.0)) > 1e-6:
        if np.ptp(scales) <= 1e-6 * max(1.0, float(scales.max())):
            return f"scale {scales[0]:.6g}"
        return "scales " + ", ".join(f"{s:.6g}" for s in scales)
    if np.linalg.det(m[:3, :3]) < 0:
        return "a reflection"
    if np.max(np.abs(m[3] - (0.0, 0.0, 0.0, 1.0))) > 1e-9:
        return "bottom row " + ", ".join(f"{v:.6g}" for v in m[3]) + "; a rigid transform's is 0, 0, 0, 1"
    if np.max(np.abs(m[:3, 3])) > TRANSLATION_MM:
        return f"translation beyond ±{TRANSLATION_MM:g} mm"
    return None
