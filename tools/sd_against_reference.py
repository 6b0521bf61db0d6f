"""Developer tool: the SDs tracking reports on the real biplane data against an independent
reference - the disagreement with the region fits of ``tools/reference_poses.py`` (which
share no code with the matcher) - per degree of freedom of the body's own motion: its
centroid (world x, y, z, mm) and its turn about its own model axes (deg).

Tracks ``--data`` from nothing, then compares every matched pose with the region fit of the
same frame and component in ``REGION_CSV`` (the ``--out`` of ``tools/reference_poses.py``
run on these poses: ``--poses`` a CSV of them). Prints per component the mean, SD and RMS
of matcher minus region fit, the median reported SD, and the reported SD over the SD and
over the RMS of the disagreement (the disagreement holds the region fit's own error too).

Usage: .venv/bin/python tools/sd_against_reference.py REGION_CSV [--data ../shared/data/biplane-tka]
"""
from __future__ import annotations

import argparse
import csv
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fluorogui import Session  # noqa: E402
from fluorogui.core.projection.pose import rotation_matrix  # noqa: E402
from fluorogui.io.importer import import_folder  # noqa: E402
from fluorogui.io.project.document import save_project  # noqa: E402

REF_KEYS = ("ref_x", "ref_y", "ref_z", "ref_alpha", "ref_beta", "ref_gamma")


def body_difference(pose, ref, centroid) -> np.ndarray:
    """Centroid difference (world mm) and the turn from ``ref`` to ``pose`` about the model's axes (deg)."""
    R, Q = rotation_matrix(*pose[3:]), rotation_matrix(*ref[3:])
    moved = (R @ centroid + pose[:3]) - (Q @ centroid + ref[:3])
    return np.r_[moved, np.degrees(Rotation.from_matrix(Q.T @ R).as_rotvec())]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("region_csv", type=Path)
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "biplane-tka")
    args = ap.parse_args(argv)
    with open(args.region_csv, newline="") as fh:
        ref = {(int(r["frame"]), r["component"]): np.array([float(r[k]) for k in REF_KEYS]) for r in csv.DictReader(fh)}
    path = Path(tempfile.mkdtemp(prefix="sd-reference-")) / "real.fluoro"
    save_project(import_folder(args.data), path)
    session = Session.open(path)
    results = [r for r in session.track() if r.status == "matched" and (r.frame, r.component) in ref]
    for component in session.components():
        rows = [r for r in results if r.component == component]
        if len(rows) < 3:
            continue
        centroid = session.mesh(component).centroid
        diff = np.array([body_difference(r.pose, ref[(r.frame, component)], centroid) for r in rows])
        sd = np.median(np.array([r.match.sd_body for r in rows], dtype=float), axis=0)
        rms, spread = np.sqrt((diff ** 2).mean(0)), diff.std(0, ddof=1)
        print(f"{component} ({len(rows)} frames): centroid x y z (mm), turn about the model's x y z (deg)")
        for label, values, fmt in (("matcher - region fit, mean", diff.mean(0), "7.3f"),
                                   ("matcher - region fit, SD", spread, "7.3f"),
                                   ("matcher - region fit, RMS", rms, "7.3f"),
                                   ("reported SD (median)", sd, "7.3f"),
                                   ("reported SD / SD of the difference", sd / spread, "7.2f"),
                                   ("reported SD / RMS of the difference", sd / rms, "7.2f")):
            print(f"  {label:36s}" + " ".join(format(v, fmt) for v in values))
    return 0


if __name__ == "__main__":
    sys.exit(main())
