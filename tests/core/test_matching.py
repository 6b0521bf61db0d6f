"""The matcher on exact outlines of a procedural femoral component (known answers)."""
import numpy as np
import pytest

from fluorogui.core.cancel import Cancelled
from fluorogui.core.matching.matcher import match
from fluorogui.core.matching.problem import MatchProblem, MatchSettings
from fluorogui.core.outlines.spline import OutlineSpline
from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import pose_difference, rotation_matrix
from fluorogui.core.projection.silhouette import mesh_silhouette
from fluorogui.simulation.phantoms import femoral_component_mesh, tibial_component_mesh
from fluorogui.simulation.protocols import dual_orthogonal_views, perturbed_starts

TRUTH = np.array([2.0, 3.0, -4.0, 10.0, 20.0, -30.0])


def _problem(mesh_fn=femoral_component_mesh, truth=TRUTH):
    mesh = prepare_mesh(*mesh_fn())
    views = dual_orthogonal_views()
    R = rotation_matrix(*truth[3:])
    splines = [OutlineSpline.fit(mesh_silhouette(mesh, R, truth[:3], v).points_px) for v in views]
    return MatchProblem(mesh, views, splines)


@pytest.mark.parametrize("mesh_fn", [femoral_component_mesh, tibial_component_mesh])
def test_fast_recovers_the_pose_from_perturbed_starts(mesh_fn):
    problem = _problem(mesh_fn)
    starts = perturbed_starts(TRUTH, 4, np.random.default_rng(7))
    for start in starts:
        res = match(problem, start, MatchSettings(method="fast"))
        err = pose_difference(res.pose, TRUTH)
        assert res.converged, res.message
        # exact outlines: measured at most 0.00069 mm, 0.0046 deg, objective 0.0023 mm (one start of
        # the femur's four, stopped at the objective's noise floor; the rest within 0.0004 mm,
        # 0.0020 deg; before the silhouette's cell drawing 0.00067 mm, 0.0020 deg)
        assert np.all(np.abs(err[:3]) < 0.0014) and np.all(np.abs(err[3:]) < 0.0092), err
        assert res.objective_mm < 0.003 and len(res.per_view_mean_mm) == 2
        assert res.method == "fast" and res.calls > 1 and res.seconds > 0


@pytest.mark.slow
def test_paper_method_improves_on_the_start_and_reports_its_record():
    """The paper's method (BFGS with finite differences on the mean distance of the point
    cloud's grid outline) on exact outlines from a start 3 / 2 / 2 mm and degrees off.
    Measured: it never meets its own stopping rule here. With SciPy 1.16 it ended at the call
    limit in 300 calls, and given 800 stopped after 712 ("precision loss": the grid outline's
    distance is not smooth at the 0.1 mm / deg difference step) at the same best pose; with
    SciPy 1.17.1 its line search gives up the same way after 299 calls, whether 300 or 800 are
    allowed. Either way it is not converged and says why."""
    problem = _problem()
    start = TRUTH + np.array([3.0, -2.0, 2.0, 3.0, -2.0, 2.0])
    calls = []
    res = match(problem, start, MatchSettings(method="paper", model_points=3500, outline_points=50, max_calls=300),
                progress=lambda n, value, pose: calls.append((n, value)))
    start_error = np.abs(pose_difference(start, TRUTH))
    error = np.abs(pose_difference(res.pose, TRUTH))
    assert np.all(np.abs(pose_difference(res.pose, TRUTH))[:3] < start_error[:3])
    assert res.calls <= 300 and res.method == "paper"
    assert calls[0][0] == 1 and calls[-1][0] == res.calls
    assert res.objective_mm < calls[0][1]
    # not converged, and it says why
    assert not res.converged and (res.message == "call limit reached"
                                 or res.message.startswith("BFGS stopped: ")), res.message
    # what it achieves: the objective 5.30 -> 0.95 mm (0.45 / 0.50 per view); translation
    # 0.34 / 0.14 / 0.12 mm; angles 0.87 / 1.19 / 1.03 deg (from 3 / 2 / 2). Its path through
    # the non-smooth objective moves with the exact outlines' sampling: before the
    # silhouette's cell drawing 0.23 / 0.34 / 0.33 mm and 2.51 / 0.53 / 0.87 deg
    assert calls[0][1] > 5.0 and res.objective_mm < 1.9, (calls[0][1], res.objective_mm)
    assert np.all(error[:3] < 0.69), error
    assert np.all(error[3:] < np.minimum(start_error[3:], [1.74, 2.38, 2.06])), error


@pytest.mark.parametrize("method", ["fast", "paper"])
def test_cancel_stops_at_once_and_is_reported(method):
    problem = _problem()
    seen, asked = [], []

    def cancel():
        asked.append(len(seen))
        return len(seen) >= 1

    with pytest.raises(Cancelled):
        match(problem, TRUTH + 5.0, MatchSettings(method=method, model_points=2000), progress=lambda *a: seen.append(a),
              cancel=cancel)
    assert len(seen) == 1 and asked[-1] == 1  # stopped at the first check after the first step


def test_unknown_method_is_refused():
    with pytest.raises(ValueError, match="unknown method"):
        match(_problem(), TRUTH, MatchSettings(method="nope"))


def test_result_dict_has_the_cli_contract_fields():
    res = match(_problem(), TRUTH + 1.0, MatchSettings())
    d = res.to_dict()
    for key in ("pose", "objective_mm", "per_view_mean_mm", "calls", "seconds", "converged", "method", "settings"):
        assert key in d
    assert len(d["pose"]) == 6
