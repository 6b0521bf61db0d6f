"""The calibration wizard: plate fit shown and accepted, beads calibrated, views written."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pytestqt")
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "core"))
from plate_phantom import KnownDistortion, plate_image  # noqa: E402
from test_beads import PITCH, SIZE, phantom, render, two_views  # noqa: E402

from fluorogui.gui.dialogs.calibration_wizard import CalibrationWizard  # noqa: E402
from fluorogui.io.calibration import load_view  # noqa: E402
from fluorogui.io.images import write_image  # noqa: E402


def test_wizard_plate_then_beads_writes_views(qtbot, tmp_path):
    no_distortion = KnownDistortion(size=SIZE, pincushion_px=0.0, s_turn_px=0.0)
    plate, _ = plate_image(no_distortion, SIZE, "square", 16.0, hole_px=4.0)
    write_image(tmp_path / "plate1.png", plate, bits=16)
    views = two_views()
    beads = phantom(views)
    for k, view in enumerate(views):
        write_image(tmp_path / f"beads{k + 1}.png", render(view, beads), bits=16)
    (tmp_path / "beads.csv").write_text("\n".join(",".join(map(repr, map(float, b))) for b in beads) + "\n")

    wizard = CalibrationWizard()
    qtbot.addWidget(wizard)
    wizard.show()
    page = wizard.plate_page
    page.plates[0].setText(str(tmp_path / "plate1.png"))
    page.spacing.setValue(2.0)
    assert not page.isComplete()
    page.run_button.click()
    qtbot.waitUntil(lambda: page.isComplete(), timeout=30000)
    assert "residual RMS" in page.texts[0].text() and not page.pictures[0].pixmap().isNull()
    assert set(page.corrections) == {0}
    wizard.next()

    beads_page = wizard.bead_page
    for k in range(2):
        beads_page.images[k].setText(str(tmp_path / f"beads{k + 1}.png"))
    beads_page.phantom.setText(str(tmp_path / "beads.csv"))
    beads_page.pitch.setValue(PITCH)
    beads_page.out_dir.setText(str(tmp_path / "out"))
    beads_page.run_button.click()
    qtbot.waitUntil(lambda: beads_page.isComplete(), timeout=30000)
    assert all("reprojection RMS" in beads_page.texts[k].text() for k in range(2))
    for k in range(2):
        assert beads_page.results[k].rms_px < 0.1
    wizard.accept()
    assert [p.name for p in wizard.written] == ["view1_mayacam2.txt", "view1.json", "view2_mayacam2.txt", "view2.json"]
    assert "distortion" in load_view(tmp_path / "out" / "view1.json").extra
    assert "distortion" not in load_view(tmp_path / "out" / "view2.json").extra
    for k, view in enumerate(views):
        fitted = load_view(tmp_path / "out" / f"view{k + 1}_mayacam2.txt")
        probe = np.random.default_rng(0).uniform(-50, 50, (10, 3))
        assert np.abs(fitted.project(probe) - view.project(probe)).max() < 0.3


def test_wizard_shows_a_bad_plate(qtbot, tmp_path):
    write_image(tmp_path / "blank.png", np.full((64, 64), 0.5))
    wizard = CalibrationWizard()
    qtbot.addWidget(wizard)
    wizard.show()
    wizard.plate_page.plates[0].setText(str(tmp_path / "blank.png"))
    wizard.plate_page.run_button.click()
    qtbot.waitUntil(lambda: "no grid" in wizard.plate_page.status.text(), timeout=10000)
    assert "blank.png" in wizard.plate_page.status.text() and not wizard.plate_page.isComplete()
