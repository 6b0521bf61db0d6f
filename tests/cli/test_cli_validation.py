"""`fluorogui validate idealized`, small cases end to end: on the independent X-ray model
(default) and on the old filled-silhouette images."""
import csv
import json

import numpy as np
import pytest

from fluorogui.cli import main
from fluorogui.core.phantoms import tibial_component_mesh


@pytest.fixture(scope="module")
def tray(tmp_path_factory):
    import pyvista as pv

    v, f = tibial_component_mesh()
    model = tmp_path_factory.mktemp("mesh") / "tray.stl"
    pv.PolyData(v, np.column_stack([np.full(len(f), 3), f]).ravel()).save(str(model))
    return str(model)


def _run(tray, out_dir, capsys, *extra):
    code = main(["validate", "idealized", "--model", tray, "--flexion", "45", "--starts", "3",
                 "--image-size", "512", "--out", str(out_dir), *extra])
    out = capsys.readouterr().out
    assert code == 0
    rows = list(csv.DictReader(open(out_dir / "results.csv")))
    return out, rows, json.loads((out_dir / "results.json").read_text())


def _errors(payload):
    return np.abs(np.array([e for case in payload["cases"] for e in case["errors"]]))


def test_small_idealized_case_on_xray_images(tray, tmp_path, capsys):
    out, rows, payload = _run(tray, tmp_path, capsys, "--variant", "none", "mirrored", "--angle", "70", "--tilt", "10")
    assert "xray images, views 70 deg apart, tilt 10 deg" in out and "tray.stl (mirrored)" in out
    for column in ("conv", "right", "false", "worst mm/deg"):
        assert column in out
    assert payload["renderer"] == "xray" and len(rows) == 2 and all(int(r["n_runs"]) == 3 for r in rows)
    assert all(len(run["sd"]) == 6 for case in payload["cases"] for run in case["runs"])
    # the edges of real (blurred, thin-rimmed) metal sit inside its silhouette, which the
    # matcher does not model yet: measured worst 0.17 mm / 0.31 deg at 512 px (see README)
    err = _errors(payload)
    assert err[:, :3].max() < 0.3 and err[:, 3:].max() < 0.5, err


def test_small_idealized_case_on_silhouette_images_lands_every_start(tray, tmp_path, capsys):
    out, rows, payload = _run(tray, tmp_path, capsys, "--renderer", "silhouette", "--tilt", "10")
    assert "silhouette images" in out and payload["renderer"] == "silhouette"
    err = _errors(payload)
    assert err[:, :3].max() < 0.015 and err[:, 3:].max() < 0.05, err  # measured 0.008 mm / 0.034 deg (512 px)
    assert rows[0]["right_basin"] == "3" and rows[0]["false_converged"] == "0"
