"""The inputs the commands load, one way for all of them: calibrations (with their
distortion corrections), images of a view, implant meshes, start poses, outline files and
match settings. Each refuses bad input with one ``InputError`` naming the file or a
``UsageError`` naming the option."""
from __future__ import annotations

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
    from fluorogui.io.corrections import read_view_image

    if len(paths or []) != len(views):
        raise UsageError(f"fluorogui: give one --image per --camera ({len(views)}), got {len(paths or [])}; "
                          "FILE@N picks frame N of a multi-frame DICOM or video")
    return [read_view_image(p, v) for p, v in zip(paths, views)]


def load_model(path):
    """An implant mesh prepared for matching, read as the session reads its models."""
    from fluorogui.workflow.session import prepared_model, read_model

    return prepared_model(path, *read_model(path))


def start_pose(values, what="--start"):
    from fluorogui.core.projection.pose import as_pose

    try:
        return as_pose(values)
    except ValueError as exc:
        raise UsageError(f"fluorogui: {what}: {exc}") from None


def outline_splines(outline_paths, images, image_paths, views, mesh, pose):
    """Splines from given outline files, or segmented from the images near the pose."""
    from fluorogui.core.matching.loop import predicted_outline
    from fluorogui.core.outlines.edges import component_outline
    from fluorogui.core.outlines.spline import OutlineError, OutlineSpline
    from fluorogui.io.errors import InputError
    from fluorogui.io.outlines import read_outline_csv

    if outline_paths and len(outline_paths) != len(views):
        raise UsageError(f"fluorogui: give one --outline per view or none (got {len(outline_paths)})")
    splines = []
    for k, view in enumerate(views):
        if outline_paths:
            source, points = outline_paths[k], read_outline_csv(outline_paths[k])
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


def check_start_visible(views, mesh, start, image_paths) -> None:
    """Refuse a start pose that puts the component (its centroid) outside an image: the
    outline there cannot be segmented or matched."""
    from fluorogui.core.projection.pose import transform_points
    from fluorogui.io.errors import InputError

    centre = transform_points(start, mesh.centroid[None, :])
    for path, view in zip(image_paths, views):
        depth = float((centre[0] - view.source) @ view.normal)
        uv = view.project(centre)[0] if depth > 0 else np.array([np.nan, np.nan])
        w, h = view.image_size
        if not (depth > 0 and 0 <= uv[0] <= w - 1 and 0 <= uv[1] <= h - 1):
            raise InputError(path, "the start pose puts the component outside this image "
                                   f"(its centre projects to u={uv[0]:.0f}, v={uv[1]:.0f}; image {w}x{h})")
