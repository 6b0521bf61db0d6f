"""The inputs the commands load, one way for all of them: calibrations (with their
distortion corrections), images of a view, implant meshes, start poses, outline files and
match settings. Each refuses bad input with one ``InputError`` naming the file or a
``UsageError`` naming the option; what an input needed repaired or noted is one warning
line on stderr (``input_warnings_on_stderr``)."""
from __future__ import annotations

import sys
import warnings
from contextlib import contextmanager

import numpy as np

from fluorogui.cli.common import UsageError

# -- helpers --------------------------------------------------------------------------------


def load_views(paths):
    from fluorogui.io.calibration import load_view

    if len(paths) not in (1, 2):
        raise UsageError(f"fluorogui: give two --camera files, or one for a single-plane view (got {len(paths)})")
    return [load_view(p, name=f"view {k + 1}") for k, p in enumerate(paths)]


def with_corrections(views, paths):
    """The views carrying their distortion corrections (one file per view), if any."""
    from fluorogui.io.corrections import attach_correction, load_correction

    if not paths:
        return views
    if len(paths) != len(views):
        raise UsageError(f"fluorogui: give one --correction per --camera ({len(views)}), got {len(paths)}")
    return [attach_correction(v, load_correction(p)) for v, p in zip(views, paths)]


def load_images(paths, views):
    """The images to match, one per view (``io.corrections.read_view_image``: damaged,
    blank or wrongly sized ones refused, naming the file)."""
    from fluorogui.io.corrections import read_view_image

    if len(paths or []) != len(views):
        raise UsageError(f"fluorogui: give one --image per --camera ({len(views)}), got {len(paths or [])}; "
                          "FILE@N picks frame N of a multi-frame DICOM or video")
    return [read_view_image(p, v, for_matching=True) for p, v in zip(paths, views)]


def load_model(path):
    """An implant mesh prepared for matching, read as the session reads its models."""
    from fluorogui.io.meshes.model import prepared_model, read_model

    return prepared_model(path, *read_model(path))


#: a start pose's angles beyond this (degrees) are a mistake, not a turn
MAX_ANGLE_DEG = 360.0


def start_pose(values, what="--start"):
    """Six finite numbers whose angles lie within ±``MAX_ANGLE_DEG``; else a UsageError
    naming ``what``."""
    from fluorogui.core.projection.pose import as_pose

    try:
        pose = as_pose(values)
    except ValueError as exc:
        raise UsageError(f"fluorogui: {what}: {exc}") from None
    for name, angle in zip(("ALPHA", "BETA", "GAMMA"), pose[3:]):
        if abs(angle) > MAX_ANGLE_DEG:
            raise UsageError(f"fluorogui: {what}: {name} = {angle:.4g}° is beyond ±{MAX_ANGLE_DEG:g}°; "
                             "give the angles in degrees")
    return pose


def read_outline(path, view):
    """An outline file's points (``io.outlines.read_outline_csv``), refused naming the file
    when they lie far outside the view's image (``io.outlines.check_outline_in_image``) or
    do not make a closed outline."""
    from fluorogui.core.outlines.spline import OutlineError, OutlineSpline
    from fluorogui.io.errors import InputError
    from fluorogui.io.outlines import check_outline_in_image, read_outline_csv

    points = read_outline_csv(path)
    check_outline_in_image(points, view.image_size, path, view.name)
    try:
        OutlineSpline.fit(points)
    except (OutlineError, ValueError) as exc:
        raise InputError(path, str(exc)) from None
    return points


def outline_splines(outline_paths, images, image_paths, views, *, mesh, pose):
    """Splines from given outline files, or segmented from the images near the pose."""
    from fluorogui.core.matching.loop import predicted_outline
    from fluorogui.core.outlines.edges import component_outline
    from fluorogui.core.outlines.spline import OutlineError, OutlineSpline
    from fluorogui.io.errors import InputError

    if outline_paths and len(outline_paths) != len(views):
        raise UsageError(f"fluorogui: give one --outline per view or none (got {len(outline_paths)})")
    splines = []
    for k, view in enumerate(views):
        if outline_paths:
            source, points = outline_paths[k], read_outline(outline_paths[k], view)
        else:
            source = image_paths[k]
            try:
                points = component_outline(images[k], predicted_outline(mesh, pose, view))
            except ValueError as exc:
                raise InputError(source, f"no outline of the component found near the start pose ({exc})") from None
        try:
            splines.append(OutlineSpline.fit(points))
        except (OutlineError, ValueError) as exc:
            raise InputError(source, str(exc)) from None
    return splines


def match_settings(args, method=None, multistart: bool = True):
    """Match settings from the options; validations pass ``multistart=False`` because their
    --starts counts perturbed starts, each one match."""
    from fluorogui.core.matching.problem import MatchSettings

    method = method or args.method
    outline_points = args.outline_points
    if method == "paper" and outline_points is None:
        outline_points = 60
    return MatchSettings(method=method, model_points=getattr(args, "points", 15000),
                         outline_points=outline_points,
                         starts=max(1, getattr(args, "starts", 1)) if multistart else 1)


#: a start pose is refused when the component would be smaller than this in an image (px)
MIN_COMPONENT_PX = 4.0


def check_start_visible(views, mesh, start, image_paths, *, what: str = "--start") -> None:
    """Refuse a start pose the views cannot see, as a mistake in ``what`` (UsageError, exit 2):
    the component's centre at or behind a view's X-ray source, so close to it that the
    component would be over four times the image across, outside an image, or so far away
    that it would be a speck. The outline there could not be segmented or matched. (Not
    "beyond the intensifier": a calibration without a pixel pitch, saved as JSON, has only
    a nominal source-intensifier distance.)"""
    from fluorogui.core.projection.pose import transform_points

    centre = transform_points(start, mesh.centroid[None, :])[0]
    for k, (path, view) in enumerate(zip(image_paths, views)):
        name = f"view {k + 1}"
        depth = float((centre - view.source) @ view.normal)
        if depth <= 0:
            raise UsageError(f"fluorogui: {what}: the pose lies behind the source of {name} "
                             f"(its centre is {-depth:.4g} mm behind it)")
        if depth <= mesh.radius:
            raise UsageError(f"fluorogui: {what}: the pose lies at the source of {name} "
                             f"(its centre is {depth:.4g} mm in front of it, within the component's size)")
        w, h = view.image_size
        across = 2.0 * mesh.radius * float(np.mean(view.focal_px)) / depth
        if across > 4.0 * max(w, h):
            raise UsageError(f"fluorogui: {what}: the pose lies too close to the source of {name} ({depth:.4g} mm "
                             f"from it): the component would be {across:.0f} px across in a {w}x{h} px image")
        u, v = view.project(centre[None, :])[0]
        if not (0 <= u <= w - 1 and 0 <= v <= h - 1):
            raise UsageError(f"fluorogui: {what}: the pose puts the component outside this image of {name} "
                             f"({path}: its centre projects to u={u:.0f}, v={v:.0f}; the image is {w}x{h} px)")
        if across < MIN_COMPONENT_PX:
            raise UsageError(f"fluorogui: {what}: the pose lies too far from the source of {name} ({depth:.4g} mm "
                             f"from it): the component would be {across:.2g} px across")


@contextmanager
def input_warnings_on_stderr():
    """While the block runs, every ``InputWarning`` (an input repaired, or accepted with a
    note) is one line on stderr, ``fluorogui: warning: <file>: <what>``; other warnings keep
    going to the log."""
    from fluorogui.io.errors import InputWarning

    with warnings.catch_warnings():
        shown = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):  # warnings.showwarning's signature
            if issubclass(category, InputWarning):
                print(f"fluorogui: warning: {message}", file=sys.stderr, flush=True)
            else:
                shown(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        warnings.simplefilter("always", InputWarning)
        yield
