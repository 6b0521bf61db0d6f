"""``fluorogui calibrate distortion`` and ``fluorogui calibrate geometry``: fluoroscope set-up
from a perforated-plate image and from bead-phantom images (thin layers over
``fluorogui.core.distortion`` and ``fluorogui.core.beads``)."""
from __future__ import annotations

from pathlib import Path

from fluorogui.commands.common import UsageError


def add_parsers(sub) -> None:
    c = sub.add_parser("calibrate", help="distortion correction (plate) and view geometry (bead phantom)")
    cs = c.add_subparsers(dest="what", required=True)
    d = cs.add_parser("distortion", help="a distortion correction from a perforated-plate image")
    d.add_argument("--plate", required=True, metavar="IMG", help="plate image (FILE@N for a frame)")
    d.add_argument("--spacing", required=True, type=float, metavar="MM", help="hole spacing in mm")
    d.add_argument("--grid", choices=["square", "hex"], default="square")
    d.add_argument("--model", choices=["global", "local"], default="global",
                   help="global polynomial (Gronenschild) or local weighted mean (XMALab-like)")
    d.add_argument("--degree", type=int, default=5, help="degree of the global polynomial (default 5)")
    d.add_argument("--out", required=True, metavar="CORR.json")
    d.add_argument("--picture", metavar="PNG", help="also write the residual picture")
    d.set_defaults(func=run_distortion)

    g = cs.add_parser("geometry", help="view geometry from images of a bead phantom")
    g.add_argument("--image", action="append", required=True, metavar="IMG", help="phantom image per view")
    g.add_argument("--phantom", required=True, metavar="BEADS.csv", help="bead coordinates x,y,z (mm)")
    g.add_argument("--correction", action="append", metavar="CORR.json", help="distortion correction per view")
    g.add_argument("--pitch", type=float, default=None, metavar="MM", help="detector pixel pitch to record")
    g.add_argument("--out-dir", required=True, metavar="DIR")
    g.set_defaults(func=run_geometry)


def _load_image(path):
    from fluorogui.io.images import read_image

    return read_image(path)


def run_distortion(args) -> int:
    from fluorogui.core.distortion import DistortionError, fit_plate, residual_picture
    from fluorogui.io.corrections import save_correction
    from fluorogui.io.errors import InputError
    from fluorogui.io.images import write_rgb_png

    if args.spacing <= 0:
        raise UsageError("fluorogui: calibrate distortion: --spacing must be positive")
    if not 2 <= args.degree <= 9:
        raise UsageError("fluorogui: calibrate distortion: --degree must be 2 to 9")
    image = _load_image(args.plate)
    try:
        fit = fit_plate(image, args.spacing, args.grid, args.model, degree=args.degree)
    except DistortionError as exc:
        raise InputError(args.plate, str(exc)) from None
    save_correction(fit, args.out, args.plate)
    s = fit.summary()
    print(f"{args.plate}: {s['holes']} holes on a {args.grid} grid ({s['discarded']} blobs discarded), "
          f"{s['mm_per_px']:.4f} mm/px at the plate")
    print(f"residual RMS {s['rms_px']:.4f} px ({s['rms_mm']:.4f} mm), max {s['max_px']:.4f} px ({s['max_mm']:.4f} mm)")
    if "left_out_rms_px" in s:
        print(f"each hole left out of the local fits: RMS {s['left_out_rms_px']:.4f} px, "
              f"max {s['left_out_max_px']:.4f} px")
    if args.picture:
        write_rgb_png(args.picture, residual_picture(image, fit))
        print(f"wrote {args.picture}")
    print(f"wrote {args.out}")
    return 0


def run_geometry(args) -> int:
    from fluorogui.core.beads import BeadError, calibrate_view
    from fluorogui.io.beads import read_phantom_csv
    from fluorogui.io.calibration import save_view_mayacam2
    from fluorogui.core.distortion import correction_from_dict
    from fluorogui.io.corrections import attach_correction, load_correction
    from fluorogui.io.errors import InputError

    if args.correction and len(args.correction) != len(args.image):
        raise UsageError(f"fluorogui: calibrate geometry: give one --correction per --image or none "
                         f"(got {len(args.correction)} for {len(args.image)})")
    beads = read_phantom_csv(args.phantom)
    out_dir = Path(args.out_dir)
    results = []
    for k, image_path in enumerate(args.image):
        image = _load_image(image_path)
        correction = load_correction(args.correction[k]) if args.correction else None
        try:
            model = None if correction is None else correction_from_dict(correction)
            result = calibrate_view(image, beads, correction=model, pitch=args.pitch, name=f"view {k + 1}")
        except BeadError as exc:
            source = args.phantom if exc.about_phantom else image_path
            raise InputError(source, str(exc)) from None
        view = result.view if correction is None else attach_correction(result.view, correction)
        results.append((image_path, result, view))
    out_dir.mkdir(parents=True, exist_ok=True)
    for k, (image_path, result, view) in enumerate(results):
        target = out_dir / f"view{k + 1}_mayacam2.txt"
        save_view_mayacam2(view, target)
        print(f"view {k + 1} ({image_path}): {result.used} of {len(beads)} beads, reprojection RMS "
              f"{result.rms_px:.4f} px (max {result.max_px:.4f}), source-intensifier distance "
              f"{view.distance:.2f} mm{' (pitch assumed)' if args.pitch is None else ''}; wrote {target}")
    return 0
