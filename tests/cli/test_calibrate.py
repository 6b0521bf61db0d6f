"""`fluorogui calibrate distortion | geometry`, and corrections carried by `import` and `match`."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "core"))
from plate_phantom import KnownDistortion, plate_image  # noqa: E402
from test_beads import PITCH, phantom, render, two_views  # noqa: E402

from fluorogui.cli import main  # noqa: E402
from fluorogui.io.calibration import load_view  # noqa: E402
from fluorogui.io.images import read_image, write_image  # noqa: E402


def one_line_error(capsys, *fragments):
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for fragment in fragments:
        assert fragment in err, err
    return err


def test_calibrate_distortion(tmp_path, capsys):
    image, _ = plate_image(KnownDistortion(size=(384, 384), pincushion_px=5.0, s_turn_px=2.0))
    write_image(tmp_path / "plate.png", image, bits=16)
    code = main(["calibrate", "distortion", "--plate", str(tmp_path / "plate.png"), "--spacing", "2",
                 "--out", str(tmp_path / "corr.json"), "--picture", str(tmp_path / "residuals.png")])
    out = capsys.readouterr().out
    assert code == 0 and "residual RMS" in out
    rms = float(out.split("residual RMS ")[1].split(" px")[0])
    assert rms <= 0.044  # measured 0.022
    document = json.loads((tmp_path / "corr.json").read_text())
    assert document["format"] == "fluorogui-distortion" and document["correction"]["model"] == "polynomial"
    assert document["summary"]["rms_px"] == pytest.approx(rms, abs=1e-4)
    assert read_image(tmp_path / "residuals.png").shape == (384, 384)

    noise = np.random.default_rng(0).random((200, 200))
    write_image(tmp_path / "noise.png", noise)
    assert main(["calibrate", "distortion", "--plate", str(tmp_path / "noise.png"), "--spacing", "2",
                 "--out", str(tmp_path / "none.json")]) == 2
    one_line_error(capsys, "noise.png", "no grid")
    assert not (tmp_path / "none.json").exists()


def test_calibrate_geometry_two_views(tmp_path, capsys):
    views = two_views()
    beads = phantom(views)
    images = []
    for k, view in enumerate(views):
        path = tmp_path / f"beads{k + 1}.tif"
        write_image(path, render(view, beads), bits=16)
        images += ["--image", str(path)]
    csv = tmp_path / "beads.csv"
    csv.write_text("x,y,z\n" + "\n".join(",".join(repr(float(c)) for c in b) for b in beads) + "\n")
    code = main(["calibrate", "geometry", *images, "--phantom", str(csv), "--pitch", str(PITCH),
                 "--out-dir", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0 and out.count("reprojection RMS") == 2
    for k, view in enumerate(views):
        fitted = load_view(tmp_path / "out" / f"view{k + 1}_mayacam2.txt")
        probe = np.random.default_rng(2).uniform(-60, 60, (10, 3))
        assert np.abs(fitted.project(probe) - view.project(probe)).max() < 0.0086  # measured 0.0043, 0.0034 px
    flat = tmp_path / "flat.csv"
    flat.write_text("\n".join(f"{b[0]},{b[1]},0" for b in beads) + "\n")
    assert main(["calibrate", "geometry", *images, "--phantom", str(flat), "--out-dir", str(tmp_path / "o2")]) == 2
    one_line_error(capsys, "flat.csv", "coplanar")
    assert not (tmp_path / "o2").exists()


CORRECTION = {"format": "fluorogui-distortion", "version": 1, "summary": {},
              "correction": {"model": "polynomial", "centre_px": [47.5, 47.5], "scale_px": 48.0, "degree": 3,
                             "coef_u": [0.0, 0.0, 0.0, 0.004, 0.0, 0.004, 0.0],
                             "coef_v": [0.0, 0.0, 0.0, 0.0, 0.004, 0.0, 0.004]}}


def test_import_stores_corrections_and_the_session_applies_them(tmp_path, capsys):
    from fluorogui.core.calibration.distortion import correction_from_dict
    from fluorogui.io.project.document import load_project
    from fluorogui.simulation.demo import build_demo_project
    from fluorogui.workflow.session import Session

    data = tmp_path / "demo"
    build_demo_project(data, frames=2, image_size=96)
    (tmp_path / "corr.json").write_text(json.dumps(CORRECTION))
    out = tmp_path / "p.fluoro"
    assert main(["import", "--out", str(out), "--camera", str(data / "calibration/cam1.json"),
                 "--camera", str(data / "calibration/cam2.json"), "--images1", str(data / "cam1"),
                 "--images2", str(data / "cam2"), "--model", f"femoral={data / 'models/femoral_component.stl'}",
                 "--correction", str(tmp_path / "corr.json"), "--correction", str(tmp_path / "corr.json")]) == 0
    project = load_project(out)
    assert all(v.extra["distortion"] == CORRECTION["correction"] for v in project.views)
    session = Session(project)
    raw = read_image(project.sequences[0].paths[0])
    expected = correction_from_dict(CORRECTION["correction"]).correct_image(raw)
    np.testing.assert_array_equal(session.image(project.frames[0], 0), expected)
    assert np.abs(expected - raw).max() > 0.05  # the correction does move the picture
    (tmp_path / "bad.json").write_text('{"format": "fluorogui-distortion", "version": 1, "correction": {}}')
    assert main(["import", "--out", str(tmp_path / "q.fluoro"), "--camera", str(data / "calibration/cam1.json"),
                 "--camera", str(data / "calibration/cam2.json"), "--images1", str(data / "cam1"),
                 "--images2", str(data / "cam2"), "--model", f"femoral={data / 'models/femoral_component.stl'}",
                 "--correction", str(tmp_path / "bad.json"), "--correction", str(tmp_path / "bad.json")]) == 2
    one_line_error(capsys, "bad.json")
    assert not (tmp_path / "q.fluoro").exists()
    image = str(project.sequences[0].paths[0])
    assert main(["match", "--camera", str(data / "calibration/cam1.json"), "--image", image,
                 "--model", str(data / "models/femoral_component.stl"), "--start", "0", "0", "0", "0", "0", "0",
                 "--correction", str(tmp_path / "corr.json"), "--correction", str(tmp_path / "corr.json")]) == 2
    one_line_error(capsys, "one --correction per --camera")
