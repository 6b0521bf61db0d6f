"""Bead correspondence on generated cages whose designs make it ambiguous: regular grids on
parallel plates (seen along the plates' normal, from close by, partly outside the image) and
phantom files that break the contract. The images come from ``simulation.cages`` (ray-traced
spheres, blur and noise), not from the code under test; a pair is right when its blob lies on
the bead's true projection."""
from __future__ import annotations

import numpy as np
import pytest

from fluorogui.core.calibration.beads import BeadError, calibrate_view, detect_beads
from fluorogui.simulation.cages import helix_cage, oblique_camera, render_cage, two_plate_grid_cage

GRID = two_plate_grid_cage()


def wrong_pairs(cage, camera, image, pairs) -> list[tuple[int, int]]:
    """Pairs whose blob is more than 1 px from its bead's true projection (blob centres of
    right pairs are within 0.1 px; a neighbour is a grid node, 20 px or more, away)."""
    centres, _ = detect_beads(image)
    truth, _ = camera.project(cage.beads)
    return [(i, j) for i, j in pairs if np.linalg.norm(centres[j] - truth[i]) > 1.0]


# (tilt, azimuth, roll, source-to-cage mm, aim mm, noise, seed): the first was matched with
# one plate a column over (20 of 26 beads) before hypotheses were scored in perspective
GRID_VIEWS = [
    (6.228, 103.799, 31.004, 766.227, (9.291, 1.814, -6.347), 0.0153, 16),
    (0.0, 0.0, 0.0, 750.0, (0.0, 0.0, 0.0), 0.012, 0),
    (45.0, 200.0, 10.0, 750.0, (0.0, 0.0, 0.0), 0.012, 1),
    (25.0, 300.0, -120.0, 620.0, (10.0, -10.0, 5.0), 0.03, 2),
]


@pytest.mark.parametrize("tilt, azimuth, roll, distance, aim, noise, seed", GRID_VIEWS)
def test_two_plate_grid_matched_right(tilt, azimuth, roll, distance, aim, noise, seed):
    camera = oblique_camera(tilt, azimuth_deg=azimuth, roll_deg=roll, source_to_cage=distance, aim=aim)
    image = render_cage(GRID, camera, seed=seed, noise=noise)
    result = calibrate_view(image, GRID.beads, pitch=camera.pitch)
    assert wrong_pairs(GRID, camera, image, result.pairs) == []
    assert result.used >= result.detections - 2  # measured: all but merged blobs (0-2)
    assert np.linalg.norm(result.view.source - camera.source) < 1.0  # measured 0.01-0.2 mm


def test_deep_cage_from_close_by_matched_right():
    """Plates 200 mm apart 523 mm from the source (the near plate 1.5x the far one's scale),
    three beads outside the image: matched with four wrong pairs before."""
    cage = two_plate_grid_cage(plate_gap=200.0)
    camera = oblique_camera(17.6, azimuth_deg=159.7, roll_deg=-85.9, source_to_cage=523.3, aim=(-14.5, -7.6, 10.8))
    image = render_cage(cage, camera, seed=22, noise=0.0091)
    result = calibrate_view(image, cage.beads, pitch=camera.pitch)
    assert wrong_pairs(cage, camera, image, result.pairs) == []
    assert result.used >= result.detections - 1  # measured 22 of 23 (two beads merged)
    assert np.linalg.norm(result.view.source - camera.source) < 0.5  # measured 0.07 mm


def test_cage_with_its_extreme_beads_outside_the_image():
    """Half of one plate outside the image, with every bead of the first round of bases:
    refused before bases came in rounds."""
    cage = two_plate_grid_cage(plate_gap=200.0)
    camera = oblique_camera(51.5, azimuth_deg=121.4, roll_deg=105.7, source_to_cage=699.5, aim=(2.8, 7.1, 0.0))
    image = render_cage(cage, camera, seed=15, noise=0.0223)
    result = calibrate_view(image, cage.beads, pitch=camera.pitch)
    assert wrong_pairs(cage, camera, image, result.pairs) == []
    assert result.used == result.detections  # measured 22 of 22


def test_dense_grid_along_the_normal_not_seen_from_the_other_side():
    """Two like 6x6 plates seen along their normal: the cage seen as from its other side fits
    64 blobs to 0.04 px, with the marker bead 8 px off the marker blob (it was taken)."""
    cage = two_plate_grid_cage(spacing=20.0, grid_a=(6, 6), grid_b=(6, 6), marker_node=(1, 4))
    camera = oblique_camera(0.9, azimuth_deg=336.0, roll_deg=-149.1, source_to_cage=922.5, aim=(-4.0, 13.5, -3.0))
    image = render_cage(cage, camera, seed=6, noise=0.0284)
    result = calibrate_view(image, cage.beads, pitch=camera.pitch)
    assert wrong_pairs(cage, camera, image, result.pairs) == []
    assert np.linalg.norm(result.view.source - camera.source) < 1.0  # measured 0.1 mm


@pytest.mark.slow
def test_dense_grid_sheared_match_with_its_principal_point_inside_the_image_refused():
    """A 6x6 grid at 6 degrees whose plate matched a node over (DLT RMS 0.014 px) moves the
    principal point 610 px towards a corner, inside the image: its pixels' skew, which a
    zero-skew pinhole cannot fit (0.35 px), gives it away."""
    cage = two_plate_grid_cage(spacing=20.0, grid_a=(6, 6), grid_b=(6, 6), marker_node=(1, 4))
    camera = oblique_camera(5.567, azimuth_deg=336.735, roll_deg=-48.552, source_to_cage=587.919, aim=(-15.0,
                                                                                                       -13.187, -8.560))
    image = render_cage(cage, camera, seed=25, noise=0.0154)
    result = calibrate_view(image, cage.beads, pitch=camera.pitch)
    assert wrong_pairs(cage, camera, image, result.pairs) == []
    assert np.linalg.norm(result.view.source - camera.source) < 0.5  # measured 0.03 mm


def test_merged_blobs_left_out():
    """Plates 60 mm apart seen at 12 degrees: six of the 20 blobs are two beads merged, two
    of them were paired 1.7 and 1.95 px off (the source 14 mm off)."""
    cage = two_plate_grid_cage(plate_gap=60.0)
    camera = oblique_camera(12.389, azimuth_deg=275.372, roll_deg=15.676, source_to_cage=958.521, aim=(0.319, 11.065,
                                                                                                       -5.705))
    image = render_cage(cage, camera, seed=75, noise=0.0138)
    result = calibrate_view(image, cage.beads, pitch=camera.pitch)
    assert wrong_pairs(cage, camera, image, result.pairs) == []
    assert result.used == 14 and result.rms_px <= 0.07  # measured 14 of 20 blobs, 0.034 px
    assert np.linalg.norm(result.view.source - camera.source) < 11.3  # measured 5.6 mm: 14 beads, mostly one plate


@pytest.mark.slow
def test_marker_outside_the_image_refused():
    """Plates 200 mm apart 530 mm from the source, the marker outside the image: the near
    plate's beads look as large as a marker, and the cage seen from its other side fitted
    20 of them to 0.011 px before the marker's size was checked with perspective taken out."""
    cage = two_plate_grid_cage(plate_gap=200.0)
    camera = oblique_camera(28.663, azimuth_deg=256.446, roll_deg=-8.244, source_to_cage=529.585, aim=(1.865, -12.4,
                                                                                                       12.88))
    image = render_cage(cage, camera, seed=41, noise=0.0128)
    with pytest.raises(BeadError, match="cannot be matched.*is the marker bead in the image"):
        calibrate_view(image, cage.beads, pitch=camera.pitch)


@pytest.mark.slow
def test_phantom_files_that_break_the_contract_are_refused():
    camera = oblique_camera(30.0, azimuth_deg=120.0, roll_deg=-10.0)
    image = render_cage(GRID, camera, seed=3)
    with pytest.raises(BeadError, match="cannot be matched.*is the marker bead in the image, and the phan") as info:
        calibrate_view(image, np.roll(GRID.beads, -1, axis=0))  # the marker listed last
    assert "of the 28 detected beads" in str(info.value)
    with pytest.raises(BeadError, match="only mirrored") as info:
        calibrate_view(image, GRID.beads * [1.0, -1.0, 1.0])  # left-handed coordinates
    assert info.value.about_phantom


def test_helix_matched_right():
    cage = helix_cage()
    camera = oblique_camera(20.0, azimuth_deg=300.0, roll_deg=40.0)
    image = render_cage(cage, camera, seed=4)
    result = calibrate_view(image, cage.beads, pitch=camera.pitch)
    assert wrong_pairs(cage, camera, image, result.pairs) == []
    assert result.used >= len(cage.beads) - 2  # measured 24 of 24
