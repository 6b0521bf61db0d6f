"""Distortion-correction files and their use: the correction travels with its view.

A correction file (``fluorogui calibrate distortion --out CORR.json``) is JSON:
``{"format": "fluorogui-distortion", "version": 1, "correction": {...}, "summary": {...}}``
where ``correction`` is ``fluorogui.core.calibration.distortion``'s ``to_dict()``. Attached to a view
(``attach_correction``) it is stored in ``view.extra["distortion"]``, which the view's
``to_dict`` writes into calibration JSON and project files; MayaCam 2.0's
``undistortion`` block arrives the same way. ``correct_view_image`` applies it to an image
of that view (the paper's order: correct first, then segment and match), and
``read_view_image`` reads, checks and corrects an image of a view in one step.
"""
from __future__ import annotations

import json
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np

from fluorogui.core.calibration.distortion import Correction, DistortionError, PlateFit, correction_from_dict
from fluorogui.core.projection.geometry import View
from fluorogui.io.errors import InputError, describe_os_error
from fluorogui.io.files import atomic_write_text

CORRECTION_FORMAT = "fluorogui-distortion"
CORRECTION_VERSION = 1
_built: dict[str, Correction] = {}
_built_lock = threading.Lock()


def save_correction(fit: PlateFit, path, plate_image: str = "") -> None:
    """Write a plate calibration's correction and its residual summary, atomically."""
    summary = fit.summary() | {"plate_image": str(plate_image),
                               "residual_px": [round(float(r), 5) for r in fit.residual_px]}
    document = {"format": CORRECTION_FORMAT, "version": CORRECTION_VERSION,
                "correction": fit.correction.to_dict(), "summary": summary}
    atomic_write_text(path, json.dumps(document, allow_nan=False) + "\n")


def load_correction(path) -> dict:
    """The correction dict of a correction file; InputError naming the file when it is not one."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    except UnicodeDecodeError:
        raise InputError(path, "not a text file") from None
    try:
        document = json.loads(text)
    except json.JSONDecodeError:
        raise InputError(path, "not a distortion-correction file (invalid JSON)") from None
    if not isinstance(document, dict) or document.get("format") != CORRECTION_FORMAT:
        raise InputError(path, "not a fluorogui distortion-correction file")
    if not isinstance(document.get("version"), int) or document["version"] > CORRECTION_VERSION:
        raise InputError(path, f"unsupported correction version {document.get('version')!r}")
    correction = document.get("correction")
    try:
        correction_from_dict(correction if isinstance(correction, dict) else {})
    except DistortionError as exc:
        raise InputError(path, str(exc)) from None
    return correction


def attach_correction(view: View, correction: dict) -> View:
    """A copy of ``view`` carrying ``correction`` (replacing any it had)."""
    copy = replace(view, extra=dict(view.extra))
    copy.extra["distortion"] = correction
    return copy


def view_correction(view: View) -> Correction | None:
    """The view's correction model, built once per distinct correction."""
    stored = view.extra.get("distortion")
    if not stored:
        return None
    key = json.dumps(stored, sort_keys=True)
    with _built_lock:
        if key in _built:
            return _built[key]
    try:
        model = correction_from_dict(stored)
    except DistortionError as exc:
        raise InputError(view.name or "view", str(exc)) from None
    with _built_lock:
        _built[key] = model
        while len(_built) > 8:
            _built.pop(next(iter(_built)))
    return model


def correct_view_image(image: np.ndarray, view: View | None) -> np.ndarray:
    """``image`` corrected for ``view``'s distortion, or as it is when the view has none."""
    model = view_correction(view) if view is not None else None
    return image if model is None else model.correct_image(image)


def read_view_image(path, view: View | None, for_matching: bool = False) -> np.ndarray:
    """The one reading of an image of a view (the app, tracking and the command line): the
    file read (``io.images.read_image``; ``FILE@N`` for a frame), checked against the
    view's image size and corrected for its distortion. Raises InputError naming the file.
    ``for_matching`` also refuses a blank image (``io.images.check_not_blank``), which the
    app still shows."""
    from fluorogui.io.calibration import check_image_size
    from fluorogui.io.images import check_not_blank, read_image

    image = read_image(path)
    if view is not None:
        check_image_size(view, image.shape, path)
    if for_matching:
        check_not_blank(image, path)
    return image if view is None else correct_view_image(image, view)
