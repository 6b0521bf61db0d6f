"""Calibrating a fluoroscope: the one workflow behind ``fluorogui calibrate`` and the app's
calibration wizard.

1. ``fit_plates``: per view, a distortion correction from an image of a perforated plate
   (``core.calibration.distortion.fit_plate``).
2. ``calibrate_views``: per view, the projection geometry from an image of a bead phantom
   of known layout (``core.calibration.beads.calibrate_view``), the image corrected with
   that view's plate fit first; the correction then travels with the view.
3. ``write_views``: each view as MayaCam 2.0 (XMALab, Autoscoper) and as our JSON.

Every problem is one ``InputError`` naming the file at fault (the image, or the phantom
file when the phantom cannot be matched). Long steps report ``progress(text)`` and stop
with ``Cancelled`` between views when ``cancel()`` turns true.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from fluorogui.core.calibration.beads import BeadCalibration, BeadError, calibrate_view
from fluorogui.core.calibration.distortion import DistortionError, PlateFit, correction_from_dict, fit_plate
from fluorogui.core.cancel import check_cancel
from fluorogui.core.projection.geometry import View
from fluorogui.io.beads import read_phantom_csv
from fluorogui.io.calibration import save_view_json, save_view_mayacam2
from fluorogui.io.corrections import attach_correction
from fluorogui.io.errors import InputError
from fluorogui.io.images import read_image

Progress = Callable[[str], None]


@dataclass
class PlateResult:
    """One view's plate fit and the plate image it was fitted on."""

    path: str
    fit: PlateFit
    image: np.ndarray

    @property
    def correction(self) -> dict:
        """The correction as it is stored with a view (``view.extra["distortion"]``)."""
        return self.fit.correction.to_dict()


@dataclass
class ViewResult:
    """One view's bead calibration: the fit, the view (carrying its correction) and the image."""

    path: str
    calibration: BeadCalibration
    view: View
    image: np.ndarray
    phantom_beads: int  # beads in the phantom file


def fit_plates(plates: dict[int, str], spacing_mm: float, *, grid: str = "square", model: str = "global",
               degree: int = 5, progress: Progress | None = None,
               cancel: Callable[[], bool] | None = None) -> dict[int, PlateResult]:
    """A distortion correction per view (0-based) from its plate image."""
    out = {}
    for view, path in sorted(plates.items()):
        check_cancel(cancel)
        if progress is not None:
            progress(f"view {view + 1}: fitting the plate")
        image = read_image(path)
        try:
            fit = fit_plate(image, spacing_mm, grid=grid, model=model, degree=degree)
        except DistortionError as exc:
            raise InputError(path, str(exc)) from None
        out[view] = PlateResult(str(path), fit, image)
    return out


def calibrate_views(images: dict[int, str], phantom_path, *, corrections: dict[int, dict] | None = None,
                    pitch: float | None = None, progress: Progress | None = None,
                    cancel: Callable[[], bool] | None = None) -> dict[int, ViewResult]:
    """The geometry of every view (0-based) from its bead image; ``corrections`` (per view,
    as ``PlateResult.correction`` or a correction file's content) are applied first and
    attached to the views."""
    beads = read_phantom_csv(phantom_path)
    corrections = corrections or {}
    out = {}
    for view, path in sorted(images.items()):
        check_cancel(cancel)
        if progress is not None:
            progress(f"view {view + 1}: calibrating")
        image = read_image(path)
        correction = corrections.get(view)
        try:
            model = None if correction is None else correction_from_dict(correction)
            result = calibrate_view(image, beads, correction=model, pitch=pitch, name=f"view {view + 1}")
        except BeadError as exc:
            raise InputError(phantom_path if exc.about_phantom else path, str(exc)) from None
        fitted = result.view if correction is None else attach_correction(result.view, correction)
        out[view] = ViewResult(str(path), result, fitted, image, len(beads))
    return out


def write_views(views: dict[int, View], out_dir) -> list[Path]:
    """Write each view (0-based key k) as ``view{k+1}_mayacam2.txt`` and ``view{k+1}.json``
    in ``out_dir`` (created); returns the files written, MayaCam first per view."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        from fluorogui.io.errors import describe_os_error

        raise InputError(out, f"cannot create the folder: {describe_os_error(exc)}") from None
    written = []
    for k, view in sorted(views.items()):
        mayacam, document = out / f"view{k + 1}_mayacam2.txt", out / f"view{k + 1}.json"
        save_view_mayacam2(view, mayacam)
        save_view_json(view, document)
        written += [mayacam, document]
    return written
