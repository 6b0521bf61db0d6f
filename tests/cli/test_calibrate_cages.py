"""`fluorogui calibrate geometry` on generated cages of other designs than the shipped test
phantom: a lab's two-plate grid (28 beads of 2.5 mm, plates 120 mm apart, a 5 mm marker)
and a helix, each in two views. The images come from ``simulation.cages`` (ray-traced
spheres, blur and noise); the fitted views are compared with the cameras that made them.
``benchmarks/bench_cages.py`` prints the same numbers for more designs."""
from __future__ import annotations

import re

import numpy as np
import pytest

from fluorogui.cli import main
from fluorogui.io.calibration import load_view
from fluorogui.io.images import write_image
from fluorogui.simulation.cages import (
    Cage,
    helix_cage,
    render_cage,
    two_plate_grid_cage,
    two_view_cameras,
    write_cage_scene,
)


def calibrate(tmp_path, capsys, cage) -> list[dict]:
    """Per view: beads used and in the phantom, reprojection RMS (px, as printed), and the
    fitted view's source and source-intensifier distance errors (mm)."""
    cameras = two_view_cameras()
    images, phantom = write_cage_scene(cage, cameras, tmp_path)
    arguments = [a for path in images for a in ("--image", str(path))]
    code = main(["calibrate", "geometry", *arguments, "--phantom", str(phantom), "--pitch", "0.3",
                 "--out-dir", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0, out
    results = []
    for k, camera in enumerate(cameras):
        line = next(line for line in out.splitlines() if line.startswith(f"view {k + 1} "))
        used, total = map(int, re.search(r"(\d+) of (\d+) beads", line).groups())
        view = load_view(tmp_path / "out" / f"view{k + 1}.json")
        results.append({"used": used, "total": total,
                        "rms_px": float(re.search(r"reprojection RMS ([0-9.]+) px", line).group(1)),
                        "source_mm": float(np.linalg.norm(view.source - camera.source)),
                        "distance_mm": abs(view.distance - camera.source_to_intensifier)})
    return results


def test_lab_two_plate_grid_cage(tmp_path, capsys):
    """Refused before this branch ("only 7 pairs (need 8)", "only 4 pairs"): the old detector
    found 190 blobs in the vignetted field, and its affine search failed on the two plates."""
    first, second = calibrate(tmp_path, capsys, two_plate_grid_cage())
    assert (first["used"], first["total"]) == (26, 28)  # beads overlapping in view 1: 26 blobs
    assert (second["used"], second["total"]) == (28, 28)
    assert first["rms_px"] <= 0.049 and second["rms_px"] <= 0.025  # measured 0.0245, 0.0124 px
    assert first["source_mm"] <= 0.12 and second["source_mm"] <= 0.07  # measured 0.061, 0.035 mm
    assert first["distance_mm"] <= 0.13 and second["distance_mm"] <= 0.12  # measured 0.063, 0.060 mm


def test_helix_cage(tmp_path, capsys):
    first, second = calibrate(tmp_path, capsys, helix_cage())
    assert (first["used"], second["used"], first["total"]) == (22, 23, 24)  # overlapping beads: 23 blobs in each view
    assert first["rms_px"] <= 0.024 and second["rms_px"] <= 0.031  # measured 0.0120, 0.0153 px
    assert first["source_mm"] <= 0.18 and second["source_mm"] <= 0.19  # measured 0.087, 0.095 mm
    assert first["distance_mm"] <= 0.27 and second["distance_mm"] <= 0.27  # measured 0.132, 0.132 mm


def test_marker_that_cannot_be_told_apart_is_refused_saying_so(tmp_path, capsys):
    """A 2.75 mm marker among 2.5 mm beads, one bead missing from the image: the near plate's
    beads look as large as the marker, and the refusal says how many beads were found and
    how large the largest blob is."""
    cage = two_plate_grid_cage(marker_mm=2.75)
    shown = Cage(cage.name, cage.beads[:-1], cage.diameters[:-1])
    image = tmp_path / "beads.tif"
    write_image(image, render_cage(shown, two_view_cameras()[1]), bits=16)
    (tmp_path / "phantom.csv").write_text(cage.csv_text())
    code = main(["calibrate", "geometry", "--image", str(image), "--phantom", str(tmp_path / "phantom.csv"),
                 "--out-dir", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "beads.tif" in err and "found 27 beads; the marker bead" in err and "could not be told apart" in err
    ratio = float(re.search(r"the largest blob is only ([0-9.]+)\u00d7 the median", err).group(1))
    assert ratio == pytest.approx(1.36, abs=0.1)  # measured 1.36 (need 1.8)
    assert not (tmp_path / "out").exists()
