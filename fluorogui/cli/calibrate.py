"""``fluorogui calibrate distortion`` and ``fluorogui calibrate geometry``: fluoroscope set-up
from a perforated-plate image and from bead-phantom images (thin layers over
``fluorogui.core.calibration.distortion`` and ``fluorogui.core.calibration.beads``)."""
from __future__ import annotations

from fluorogui.cli.common import UsageError


def add_parser(sub):
    c = sub.add_parser("calibrate", help="distortion correction (plate) and view geometry (bead phantom)")
    cs = c.add_subparsers(dest="what", parser_class=type(c), required=True)
    d = cs.add_parser("distortion", help="a distortion correction from a perforated-plate image")
    d.add_argument("--plate", required=True, metavar="IMG", help="plate image (FILE@N for a frame)")
    d.add_argument("--spacing", required=True, type=float, metavar="MM", help="hole spacing in mm")
    d.add_argument("--grid", choices=["square", "hex"], default="square")
    d.add_argument("--model", choices=["global", "local"], default="global",
                   help="global polynomial (Gronenschild) or local weighted mean (XMALab-like)")
    d.add_argument("--degree", type=int, default=5, help="degree of the global polynomial (default 5)")
    d.add_argument("--out", required=True, metavar="CORR.json")
    d.add_argument("--picture", metavar="PNG", help="also write the residual picture")

    g = cs.add_parser("geometry", help="view geometry from images of a bead phantom")
    g.add_argument("--image", action="append", required=True, metavar="IMG", help="phantom image per view")
    g.add_argument("--phantom", required=True, metavar="BEADS.csv", help="bead coordinates x,y,z (mm)")
    g.add_argument("--correction", action="append", metavar="CORR.json", help="distortion correction per view")
    g.add_argument("--pitch", type=float, default=None, metavar="MM", help="detector pixel pitch to record")
    g.add_argument("--out-dir", required=True, metavar="DIR")
    return c


def run(args) -> int:
    return {"distortion": run_distortion, "geometry": run_geometry}[args.what](args)


def run_distortion(args) -> int:
    from fluorogui.core.calibration.distortion import residual_picture
    from fluorogui.io.corrections import save_correction
    from fluorogui.io.images import write_rgb_png
    from fluorogui.workflow.calibration import fit_plates

    if args.spacing <= 0:
        raise UsageError("fluorogui: calibrate distortion: --spacing must be positive")
    if not 2 <= args.degree <= 9:
        raise UsageError("fluorogui: calibrate distortion: --degree must be 2 to 9")
    plate = fit_plates({0: args.plate}, args.spacing, grid=args.grid, model=args.model, degree=args.degree)[0]
    save_correction(plate.fit, args.out, args.plate)
    s = plate.fit.summary()
    print(f"{args.plate}: {s['holes']} holes on a {args.grid} grid ({s['discarded']} blobs discarded), "
          f"{s['mm_per_px']:.4f} mm/px at the plate")
    print(f"residual RMS {s['rms_px']:.4f} px ({s['rms_mm']:.4f} mm), max {s['max_px']:.4f} px ({s['max_mm']:.4f} mm)")
    if "left_out_rms_px" in s:
        print(f"each hole left out of the local fits: RMS {s['left_out_rms_px']:.4f} px, "
              f"max {s['left_out_max_px']:.4f} px")
    if args.picture:
        write_rgb_png(args.picture, residual_picture(plate.image, plate.fit))
        print(f"wrote {args.picture}")
    print(f"wrote {args.out}")
    return 0


def run_geometry(args) -> int:
    from fluorogui.io.corrections import load_correction
    from fluorogui.workflow.calibration import calibrate_views, write_views

    if args.correction and len(args.correction) != len(args.image):
        raise UsageError(f"fluorogui: calibrate geometry: give one --correction per --image or none "
                         f"(got {len(args.correction)} for {len(args.image)})")
    corrections = {k: load_correction(p) for k, p in enumerate(args.correction or [])}
    results = calibrate_views(dict(enumerate(args.image)), args.phantom, corrections=corrections, pitch=args.pitch)
    written = write_views({k: r.view for k, r in results.items()}, args.out_dir)
    for k, r in sorted(results.items()):
        print(f"view {k + 1} ({r.path}): {r.calibration.used} of {r.phantom_beads} beads, reprojection RMS "
              f"{r.calibration.rms_px:.4f} px (max {r.calibration.max_px:.4f}), source-intensifier distance "
              f"{r.view.distance:.2f} mm{' (pitch assumed)' if args.pitch is None else ''}; wrote {written[2 * k]}")
    return 0
