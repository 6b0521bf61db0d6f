"""The automatic loop's default rim mode ("auto"): it refines the outline where the image's
edge is a soft rim (the independent X-ray model's cobalt-chrome) and leaves a step edge
where Canny puts it, judging each view once per sequence."""
import numpy as np
import pytest

from fluorogui.core.matching.loop import LoopSettings, segment_and_match
from fluorogui.core.outlines.rim import is_soft
from fluorogui.core.projection.pose import pose_difference
from fluorogui.reference.xray import Body, XrayModel, xray_image
from fluorogui.simulation.protocols import two_views

VIEWS = two_views(image_size=(512, 512), pitch=315.0 / 512)
OFFSET = np.array([1.0, -1.0, 0.5, 1.0, -1.0, 1.0])


def _images(tray, mu):
    mesh, _, world = tray
    return [xray_image(v, [Body(world, mesh.faces, mu)], XrayModel(), np.random.default_rng(5)) for v in VIEWS]


def _error(result, truth):
    d = pose_difference(result.pose, truth)
    return float(np.abs(d[:3]).max()), float(np.abs(d[3:]).max())


@pytest.mark.slow
def test_auto_refines_a_soft_rim_and_leaves_a_step_edge_alone(tray, monkeypatch):
    mesh, truth, _ = tray
    start = truth + OFFSET
    soft = _images(tray, 1.0)  # cobalt-chrome: Canny's outline lies inside the silhouette
    models = [None, None]
    auto = segment_and_match(soft, VIEWS, mesh, start, loop=LoopSettings(rim="auto"), rim_models=models)
    off = segment_and_match(soft, VIEWS, mesh, start, loop=LoopSettings(rim="off"))
    assert auto.settings["rim_refined"] == [True, True]
    assert off.settings["rim_refined"] == [False, False]
    # the views share one attenuation: measured 1.063/mm for both (the truth is 1.0)
    assert all(m is not None and is_soft(m) and m.mu == pytest.approx(1.0, rel=0.13) for m in models)
    print("soft: auto", _error(auto, truth), "off", _error(off, truth))
    # the refinement removes most of Canny's inward bias: measured 0.0096 mm / 0.0122 deg
    # against 0.116 mm / 0.151 deg
    assert _error(auto, truth)[1] < 0.16 * _error(off, truth)[1]
    assert _error(auto, truth)[0] < 0.019 and _error(auto, truth)[1] < 0.024, _error(auto, truth)

    step = _images(tray, 50.0)  # a step edge, as real images fit
    models = [None, None]
    auto = segment_and_match(step, VIEWS, mesh, start, loop=LoopSettings(rim="auto"), rim_models=models)
    off = segment_and_match(step, VIEWS, mesh, start, loop=LoopSettings(rim="off"))
    assert auto.settings["rim_refined"] == [False, False]
    assert all(m is not None and not is_soft(m) for m in models)  # judged, and kept for the next frame
    np.testing.assert_array_equal(auto.pose, off.pose)

    # the next frame reuses the judgement: no fit, and no pass spent on judging again
    def no_fit(*args, **kwargs):
        raise AssertionError("the edge was judged again")
    monkeypatch.setattr("fluorogui.core.matching.loop.edge_models", no_fit)
    monkeypatch.setattr("fluorogui.core.matching.loop.refine_outlines", no_fit)
    again = segment_and_match(step, VIEWS, mesh, auto.pose, loop=LoopSettings(rim="auto"), rim_models=models)
    assert again.passes == 1 and again.settings["rim_refined"] == [False, False]


def test_loop_settings_rim_modes_and_older_projects():
    assert LoopSettings().rim == "auto"
    assert LoopSettings(rim=True).rim == "on" and LoopSettings(rim=False).rim == "off"
    # projects saved before "auto" existed (schema 4) stored the default as False:
    # tests/io/test_project.py::test_schema_4_rim_switch_loads_as_a_rim_mode
    assert LoopSettings.from_dict(LoopSettings(rim="off").to_dict()).rim == "off"
    with pytest.raises(ValueError, match="rim must be one of"):
        LoopSettings(rim="sometimes")


def test_the_views_to_judge_are_judged_together_and_come_back_in_their_own_order(monkeypatch):
    """The views whose edge is to be judged are judged in one call (``rim.edge_models``: one
    attenuation for the component's metal); the models and the soft views come back in view
    order, views without an outline or with a model already given are not judged, and a
    cancel stops the judgement."""
    from fluorogui.core.cancel import Cancelled
    from fluorogui.core.matching import loop
    from fluorogui.core.outlines.rim import STEP, RimModel

    calls = []

    def fake_edge_models(images, views, mesh, pose, *, outlines_px, excludes):
        calls.append(list(images))
        return [RimModel(1.0, 0.9) if image == 2 else STEP for image in images]  # view 3 soft, the others steps

    monkeypatch.setattr(loop, "edge_models", fake_edge_models)
    outline = np.zeros((20, 2))
    soft, models = loop.soft_edge_views([0, 1, 2, 3], [None] * 4, None, np.zeros(6),
                                        outlines=[outline, outline, outline, None], models=[None, None, None, None])
    assert soft == [2] and models == [STEP, STEP, RimModel(1.0, 0.9), None]
    assert calls == [[0, 1, 2]]  # together, in one call
    calls.clear()
    soft, models = loop.soft_edge_views([0, 1], [None] * 2, None, np.zeros(6), outlines=[outline, outline],
                                        models=[RimModel(1.2, 1.0), None])
    assert soft == [0] and models == [RimModel(1.2, 1.0), STEP] and calls == [[1]]  # a given model stays
    with pytest.raises(Cancelled):
        loop.soft_edge_views([0, 1], [None] * 2, None, np.zeros(6), outlines=[outline, outline], cancel=lambda: True)


@pytest.mark.slow
def test_the_views_of_a_component_are_judged_with_one_attenuation(tray):
    """``edge_models`` gives both views of the soft tray one attenuation (its metal's), each
    its own blur; both are soft, as each view's own ``edge_model`` finds."""
    from fluorogui.core.matching.loop import segment_outlines
    from fluorogui.core.outlines.rim import edge_model, edge_models

    mesh, truth, _ = tray
    images = _images(tray, 1.0)
    outlines = [o for o in segment_outlines(images, VIEWS, mesh, truth)]
    together = edge_models(images, VIEWS, mesh, truth, outlines_px=outlines)
    alone = [edge_model(i, v, mesh, truth, outline_px=o) for i, v, o in zip(images, VIEWS, outlines)]
    assert all(is_soft(m) for m in together + alone)
    assert together[0].mu == together[1].mu == pytest.approx(1.0, rel=0.15)


@pytest.mark.parametrize("mu", [1.0, 50.0])
def test_the_quick_fit_skips_its_finer_grid_only_where_its_verdict_is_sure(tray, monkeypatch, mu):
    """``edge_models``' quick fit needs only whether the attenuation is below
    ``MAYBE_SOFT_BELOW_MU`` (``below``): on the soft tray the finer grid about the coarse
    vertex (which cannot leave that grid) is skipped, on the step edge it is not, and the
    verdict is that of the fit with every grid (the step's models too)."""
    from fluorogui.core.matching.loop import segment_outlines
    from fluorogui.core.outlines import rim

    mesh, truth, _ = tray
    images = _images(tray, mu)
    sparse = []
    for image, view, outline in zip(images, VIEWS, segment_outlines(images, VIEWS, mesh, truth)):
        pts, _ = rim._gather(image, view, mesh, truth, points=outline[::len(outline) // rim.DECIDE_POINTS])
        sparse.append(rim._subset(pts, rim._usable(pts)))
    residual_per_mu, grids = rim._residual_per_mu, []

    def counted(*args, **kwargs):
        grids.append(args)
        return residual_per_mu(*args, **kwargs)

    monkeypatch.setattr(rim, "_residual_per_mu", counted)
    quick = dict(max_points=rim.DECIDE_POINTS, tolerance=rim.DECIDE_TOLERANCE, sigma_grid=rim.DECIDE_SIGMAS)
    skipping = rim.fit_rim_models(sparse, **quick, below=rim.MAYBE_SOFT_BELOW_MU)
    skipped_grids = len(grids)
    grids.clear()
    whole = rim.fit_rim_models(sparse, **quick)
    verdict = [models[0].mu >= rim.MAYBE_SOFT_BELOW_MU for models in (skipping, whole)]
    assert verdict[0] == verdict[1] == (mu > 2)
    if mu > 2:
        assert skipping == whole and skipped_grids == len(grids)  # a step: its models are kept, every grid made
    else:
        assert skipped_grids == 2 and len(grids) == 4  # the two views' finer grids left out
