"""``validate repeatability --reference`` on the real biplane data (skips without ../shared/data)."""
import json
from pathlib import Path

import numpy as np
import pytest

from fluorogui.cli import main

pytestmark = pytest.mark.slow  # end to end on the real data

REFERENCE = Path(__file__).resolve().parents[1] / "data" / "biplane_reference_poses.csv"


@pytest.mark.parametrize("component", ["tibial", "femoral"])
def test_repeatability_of_the_first_reference_frames(shared_data, capsys, component):
    d = shared_data / "biplane-tka"
    args = ["validate", "repeatability"]
    for k in (1, 2):
        args += ["--camera", str(d / "calibration" / f"cam{k}_mayacam2.txt")]
    args += ["--model", str(d / "models" / f"{component}_component.stl"), "--reference", str(REFERENCE),
             "--pairs", str(d / "pairs.csv"), "--component", component, "--frames", "2", "--json"]
    assert main(args) == 0
    payload = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert len(payload["cases"]) == 2
    for case in payload["cases"]:
        summary = case["summary"]
        assert summary["n_converged"] == summary["n_runs"] == 10
        sd = np.array(summary["sd"])
        # far inside the paper's in vivo bound for the tibia (Table 4: 0.29 mm, 0.25 deg).
        # Measured: SD up to 0.0022 mm and 0.036 deg (tibial), 0.0009 mm and 0.0027 deg
        # (femoral); outline distance 0.118-0.145 mm
        assert sd[:3].max() < 0.0044 and sd[3:].max() < 0.072, (case["label"], sd)
        assert max(case["per_view_mean_mm"]) < 0.25, case["per_view_mean_mm"]
