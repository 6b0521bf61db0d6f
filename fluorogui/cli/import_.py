"""``fluorogui import``: make a project from a session folder or from explicit files, with its
frame rate (``--fps``, else what a video or DICOM declares)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.cli.common import UsageError, warn
from fluorogui.cli.export import fps_value
from fluorogui.io.files import check_output_file


def add_parser(sub):
    i = sub.add_parser("import", help="make a project from a session folder or from explicit files")
    i.add_argument("folder", nargs="?", metavar="FOLDER",
                   help="a folder laid out like biplane-tka: calibration/, cam1/, cam2/, models/, pairs.csv")
    i.add_argument("--out", required=True, metavar="PROJECT.fluoro")
    i.add_argument("--camera", action="append", metavar="CAM", help="calibration file (twice; once for single-plane)")
    i.add_argument("--images1", metavar="DIR", help="images of camera 1 (folder, video or image)")
    i.add_argument("--images2", metavar="DIR", help="images of camera 2")
    i.add_argument("--pairs", metavar="CSV", help="frame,cam1,cam2 pairs (instead of --images1/--images2)")
    i.add_argument("--model", action="append", metavar="NAME=MESH", help="femoral=MESH and tibial=MESH")
    i.add_argument("--side", choices=("right", "left"), help="which knee (sets the signs of the kinematics)")
    i.add_argument("--correction", action="append", metavar="CORR.json",
                   help="distortion correction per camera, stored with its view in the project")
    i.add_argument("--fps", type=fps_value, metavar="N",
                   help="the images' frame rate (frames per second; time = frame / N) for C3D, .trc and .mot exports; "
                        "default: what a video or DICOM declares")
    i.add_argument("--force", action="store_true", help="replace an existing project file")
    return i


def run(args) -> int:
    from fluorogui.io.errors import InputError
    from fluorogui.io.importer import import_folder, import_session
    from fluorogui.io.project.document import save_project

    out = Path(args.out)
    if out.suffix.lower() != ".fluoro":
        raise UsageError(f"fluorogui: import: {args.out}: the project file name must end in .fluoro")
    if out.exists() and not args.force:
        raise InputError(out, "already exists; use --force to replace it")
    check_output_file(out)  # before the import's work
    if args.folder:
        if args.camera or args.images1 or args.images2 or args.model or args.pairs:
            raise UsageError("fluorogui: import: give a FOLDER or the explicit files, not both")
        project = import_folder(args.folder, allow_unequal=True)
    else:
        if len(args.camera or []) not in (1, 2):
            raise UsageError("fluorogui: import: give FOLDER, or two --camera files with --images1/--images2 "
                             "(or --pairs; one --camera with --images1 for single-plane) and "
                             "--model femoral=MESH --model tibial=MESH")
        models = {}
        for item in args.model or []:
            name, sep, path = item.partition("=")
            if not sep or not name or not path:
                raise UsageError(f"fluorogui: import: --model {item}: use NAME=MESH, e.g. femoral=femur.stl")
            models[name] = path
        if not models:
            raise UsageError("fluorogui: import: give --model femoral=MESH and/or --model tibial=MESH")
        single = len(args.camera) == 1
        if args.pairs is None and not (args.images1 and (args.images2 or single)):
            raise UsageError("fluorogui: import: give --images1 and --images2, or --pairs")
        if single and (args.pairs or args.images2):
            raise UsageError("fluorogui: import: one --camera (single-plane) takes --images1 only")
        sources = None if args.pairs else [Path(p) for p in (args.images1, args.images2) if p]
        project = import_session(args.camera, sources, models, pairs_csv=args.pairs, allow_unequal=True)
    if args.correction:
        from fluorogui.io.corrections import attach_correction, load_correction

        if len(args.correction) != len(project.views):
            raise UsageError(f"fluorogui: import: give one --correction per camera ({len(project.views)}), "
                             f"got {len(args.correction)}")
        project.views = [attach_correction(v, load_correction(p)) for v, p in zip(project.views, args.correction)]
    counts = [len(s.paths) for s in project.sequences]
    if len(set(counts)) > 1:
        short = min(range(len(counts)), key=lambda k: counts[k])
        warn(f"camera {short + 1} has {counts[short]} images but the project has {len(project.frames)} frames; "
             f"frames {project.frames[counts[short]]}..{project.frames[-1]} will be flagged when matched")
    _frame_rate(project, args.fps)
    if args.side:
        from fluorogui.workflow.session.knee import KNEE_KEY

        project.settings.setdefault(KNEE_KEY, {})["side"] = args.side
    save_project(project, out)
    from fluorogui.io.motion_files import stored_frame_rate

    fps = stored_frame_rate(project.settings)
    print(f"wrote {out}: {len(project.frames)} frames, {len(project.views)} views, "
          f"components {', '.join(m.component for m in project.models)}"
          + (f", {fps:g} frames per second" if fps is not None else
             ", no frame rate (the images do not say; give --fps N for C3D, .trc and .mot exports)"))
    return 0


def _frame_rate(project, fps: float | None) -> None:
    """Keep ``--fps`` (saying when the images declare another); warn when the views declare
    different rates (images that declare none are the usual case: the summary line says so)."""
    from fluorogui.io.importer import declared_frame_rates
    from fluorogui.io.motion_files import store_frame_rate, stored_frame_rate

    declared = [r for r in declared_frame_rates(project) if r is not None]
    if fps is not None:
        other = [f"{where} says {rate:g}" for rate, where in declared if abs(rate - fps) > 1e-6 * fps]
        if other:
            warn(f"--fps {fps:g} kept although {'; '.join(other)} frames per second")
        store_frame_rate(project.settings, fps, "user (--fps)")
    elif stored_frame_rate(project.settings) is None and declared:
        rates = ", ".join(f"{where}: {rate:g}" for rate, where in declared)
        warn(f"the views declare different frame rates ({rates}); no frame rate kept: give --fps N")
