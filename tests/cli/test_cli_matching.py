"""`fluorogui match` refuses what it cannot match and never reports a wrong pose as converged."""
import json

import numpy as np
import pytest

from fluorogui.cli import main
from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import transform_points
from fluorogui.io.calibration import save_view_json
from fluorogui.io.images import write_image
from fluorogui.simulation.demo import write_stl
from fluorogui.simulation.phantoms import tibial_component_mesh
from fluorogui.simulation.protocols import dual_orthogonal_views, flexion_pose
from fluorogui.simulation.render import render_fluoro


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("scene")
    v, f = tibial_component_mesh()
    mesh = prepare_mesh(v, f)
    truth = flexion_pose(v, 30.0)
    world = transform_points(truth, mesh.vertices)
    rng = np.random.default_rng(3)
    args = ["match"]
    for k, view in enumerate(dual_orthogonal_views()):
        save_view_json(view, d / f"cam{k}.json")
        args += ["--camera", str(d / f"cam{k}.json")]
    images = []
    for k, view in enumerate(dual_orthogonal_views()):
        image = render_fluoro(view, [(world, mesh.faces)], rng)
        if k == 1:  # a second image where the component is not: background and noise only
            blank = render_fluoro(view, [], rng)
            write_image(d / "blank.png", blank, bits=16)
        write_image(d / f"img{k}.png", image, bits=16)
        images.append(str(d / f"img{k}.png"))
    model = d / "tibia.stl"
    write_stl(model, v, f)
    return {"args": args, "images": images, "model": str(model), "truth": truth, "blank": str(d / "blank.png")}


def _run(scene, start, images=None, extra=()):
    args = list(scene["args"])
    for i in images or scene["images"]:
        args += ["--image", i]
    return args + ["--model", scene["model"], "--start", *[str(x) for x in start], *extra]


def test_match_reports_sd_status_and_reason(scene, capsys):
    start = scene["truth"] + np.array([2.0, -1.0, 1.0, 2.0, -2.0, 1.0])
    assert main(_run(scene, start, extra=["--json"])) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["converged"] and out["status"] == "matched" and out["reason"] == ""
    err = np.abs(np.array(out["pose"]) - scene["truth"])
    sd = np.array(out["sd"])
    assert sd.shape == (6,) and np.all(sd > 0)
    # the reported uncertainty: measured 0.0014-0.0043 mm, 0.0051-0.019 deg
    assert np.all(sd[:3] < 0.0086) and np.all(sd[3:] < 0.038), sd
    # and of the size of the error (measured at most 0.76 SD): a statistical claim, so a
    # 3-SD bound (with another noise draw the error may well reach 2 SD)
    assert np.all(err < 3 * sd), (err, sd)


@pytest.mark.parametrize("n", ["1", "2", "7"])
def test_too_few_outline_points_are_refused(scene, capsys, n):
    code = main(_run(scene, scene["truth"], extra=["--outline-points", n]))
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and f"--outline-points {n}" in err and "at least 8" in err


def test_start_outside_the_images_is_refused(scene, capsys):
    start = scene["truth"] + np.array([0.0, 0.0, 400.0, 0, 0, 0])  # 400 mm up: above both fields of view
    code = main(_run(scene, start))
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert "img0.png" in err and "outside this image" in err


@pytest.mark.slow
def test_component_missing_from_one_view_is_never_converged(scene, capsys):
    start = scene["truth"] + np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
    code = main(_run(scene, start, images=[scene["images"][0], scene["blank"]], extra=["--json"]))
    out = json.loads(capsys.readouterr().out)  # an outline of noise is found; the result must admit it
    assert code == 3 and not out["converged"] and out["status"] == "needs_review" and "view 2" in out["reason"]


@pytest.mark.slow
def test_rim_refinement_removes_the_edge_bias_of_thinning_metal_by_default(scene, tmp_path, capsys):
    from fluorogui.reference.xray import Body, XrayModel, xray_image

    v, f = tibial_component_mesh()
    world = transform_points(scene["truth"], np.asarray(v, dtype=float))
    images = []
    for k, view in enumerate(dual_orthogonal_views()):
        image = xray_image(view, [Body(world, np.asarray(f), 1.0)], XrayModel(), np.random.default_rng(k))
        write_image(tmp_path / f"xray{k}.png", image, bits=16)
        images.append(str(tmp_path / f"xray{k}.png"))
    start = scene["truth"] + np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
    errors, refined = {}, {}
    for name, extra in (("off", ["--no-rim"]), ("auto", [])):
        assert main(_run(scene, start, images, ["--json", *extra])) == 0
        payload = json.loads(capsys.readouterr().out)
        errors[name], refined[name] = np.abs(np.array(payload["pose"]) - scene["truth"]), payload["rim_refined"]
    assert refined == {"off": [False, False], "auto": [True, True]}
    # measured: --no-rim 0.101 mm / 0.207 deg (Canny's edge inside the silhouette); the
    # default finds both views' edges soft and refines them, as --rim does: 0.0027 mm / 0.0109 deg
    assert errors["off"][:3].max() > 0.05 and errors["off"][3:].max() > 0.1
    assert errors["auto"][:3].max() < 0.0054 and errors["auto"][3:].max() < 0.022, errors["auto"]
    assert main(_run(scene, start, images, ["--rim"])) == 0  # the text output says so too
    assert "outline moved for the metal's soft rim in views 1 and 2" in capsys.readouterr().out
