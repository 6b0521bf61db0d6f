"""The fast method stops at the objective's noise floor: on real outlines the cost changes by
about 1e-3 of itself from pose to pose (the outline point set changes), and a short step
whose quadratic model promises less than that cannot be told from noise. Here the objective
is a known quadratic bowl (six residuals, minimum at the origin) with a pose-dependent
ripple of about that size in its residuals, so the answer and the floor are both known."""
from types import SimpleNamespace

import numpy as np
import pytest

from fluorogui.core.matching import fast
from fluorogui.core.matching.problem import MatchSettings

A = np.diag([1.0, 2.0, 1.5, 3.0, 1.0, 0.2])  # residuals per unit of (centroid mm, rotation x radius mm)
FLOOR = 0.05  # a misfit the pose cannot remove (px^2), as a real outline has
RADIUS = 30.0


class _BowlWithRipple:
    """Stands in for ``fast._FastEvaluation``: residuals A x at the state x plus a small part
    that changes with every pose (as a real outline's point set does), and a misfit no pose
    removes."""

    def __init__(self, problem, R, c, settings, samples, params):
        w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2 * RADIUS
        x = np.r_[c, w]
        ripple = 0.005 * np.sin(1e4 * np.outer([1.0, 1.3, 0.7, 0.9, 1.1, 1.7], x).sum(1) + np.arange(6))
        self.r, self.J, self.w = [A @ x + ripple], [A], [np.ones(6)]
        self.per_view_mm = [float(np.sum(self.r[0] ** 2))]
        self.objective_mm, self.outlines_px = self.per_view_mm[0], []

    def robust_cost(self, huber):
        return 0.5 * float(np.sum(self.r[0] ** 2)) + FLOOR

    def normal_equations(self, huber):
        return A.T @ A, A.T @ self.r[0]


@pytest.fixture
def bowl(monkeypatch):
    monkeypatch.setattr(fast, "_FastEvaluation", _BowlWithRipple)
    monkeypatch.setattr(fast, "_samples_and_params", lambda problem, settings: ([np.zeros((0, 2))], [np.zeros(0)]))
    mesh = SimpleNamespace(centroid=np.zeros(3), radius=RADIUS)
    return SimpleNamespace(mesh=mesh, splines=[None])


def _match(problem, floor, monkeypatch):
    monkeypatch.setattr(fast, "NOISE_FLOOR", floor)
    settings = MatchSettings(centre_first=False)
    return fast.match_fast(problem, np.array([0.3, -0.2, 0.1, 0.4, -0.3, 0.2]), settings, None, cancel=None)


def test_a_step_promising_less_than_the_noise_ends_the_match(bowl, monkeypatch):
    assert fast.NOISE_FLOOR == 1e-3
    stopped = _match(bowl, fast.NOISE_FLOOR, monkeypatch)
    retried = _match(bowl, 0.0, monkeypatch)
    assert stopped.converged
    # measured: 7 evaluations against 12 that retry the rejected steps with more damping,
    # both within 0.009 mm / deg of the bowl's minimum (the ripple's own reach)
    assert stopped.calls + 3 <= retried.calls, (stopped.calls, retried.calls)
    assert np.abs(stopped.pose).max() < 0.018 and np.abs(retried.pose).max() < 0.018
