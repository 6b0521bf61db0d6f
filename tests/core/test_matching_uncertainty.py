"""The per-pose uncertainty (``MatchResult.sd``) against the spread over noise realisations.

The outlines are made without the matcher's code: a convex, slightly bent tri-axial
ellipsoid is projected with the pinhole formula written out here, its outline is the
convex hull of the projected vertices (exactly the silhouette of a convex mesh), resampled
every pixel, and displaced along its normal by noise correlated over a few pixels, as
edge noise after blur is. Measured (25 realisations): biplane SD / observed spread
0.85-1.34 for every DOF, single view 0.73-0.90; with every residual taken as independent
the SD came out 0.3-0.4x the spread.
"""
import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import ConvexHull

from fluorogui.core.geometry import View
from fluorogui.core.matching import MatchProblem, MatchSettings, match
from fluorogui.core.mesh import prepare_mesh
from fluorogui.core.pose import pose_difference, rotation_matrix
from fluorogui.core.spline import OutlineSpline
from fluorogui.core.validation import dual_orthogonal_views

TRUTH = np.array([3.0, -2.0, 5.0, 20.0, -15.0, 30.0])


def _egg():
    import pyvista as pv

    s = pv.Sphere(radius=1.0, theta_resolution=96, phi_resolution=72)
    p = np.asarray(s.points) * [30.0, 20.0, 12.0]
    p[:, 0] += 0.15 * p[:, 1] ** 2 / 20.0  # bent a little: no mirror symmetry
    return p, np.asarray(s.faces).reshape(-1, 4)[:, 1:]


def _noisy_outline(view: View, world: np.ndarray, noise_px: float, corr_px: float, rng) -> np.ndarray:
    d = world - view.source
    w = d @ view.normal
    uv = np.column_stack([view.principal_point[0] + view.focal_px[0] * (d @ view.e_u) / w,
                          view.principal_point[1] + view.focal_px[1] * (d @ view.e_v) / w])
    hull = uv[ConvexHull(uv).vertices]
    closed = np.vstack([hull, hull[:1]])
    arc = np.r_[0, np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))]
    s = np.arange(0, arc[-1], 1.0)
    pts = np.column_stack([np.interp(s, arc, closed[:, 0]), np.interp(s, arc, closed[:, 1])])
    tangent = np.roll(pts, -1, 0) - np.roll(pts, 1, 0)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]]) / np.linalg.norm(tangent, axis=1)[:, None]
    e = gaussian_filter1d(rng.normal(size=len(pts)), corr_px, mode="wrap")
    return pts + (e * noise_px / e.std())[:, None] * normal


def _spread(views, start_sd: float, n: int = 20, seed: int = 1):
    v, f = _egg()
    mesh = prepare_mesh(v, f)
    world = v @ rotation_matrix(*TRUTH[3:]).T + TRUTH[:3]
    rng = np.random.default_rng(seed)
    errors, sds = [], []
    for _ in range(n):
        splines = [OutlineSpline.fit(_noisy_outline(view, world, 0.1, 3.0, rng)) for view in views]
        result = match(MatchProblem(mesh, views, splines), TRUTH + rng.normal(0, start_sd, 6), MatchSettings())
        assert result.optimiser_converged, result.message
        errors.append(pose_difference(result.pose, TRUTH))
        sds.append(result.sd)
    return np.std(errors, axis=0, ddof=1), np.median(sds, axis=0)


def test_biplane_sd_matches_the_spread_over_noise_realisations():
    observed, reported = _spread(dual_orthogonal_views(), start_sd=0.5)
    ratio = reported / observed
    assert np.all(ratio > 1 / 1.5) and np.all(ratio < 1.5), (ratio, observed, reported)


def test_single_view_out_of_plane_translation_is_least_certain():
    # looking along world x: x is the out-of-plane translation
    view = View.looking_at([-1000.0, 0, 0], [0, 0, 0], [0, 0, 1], 1200.0, (1024, 1024), 315 / 1024, name="single")
    # started at the truth: from perturbed starts the single-view spread is about twice
    # the SD (the objective is rough along its flat out-of-plane valley; see the README)
    observed, reported = _spread([view], start_sd=0.0)
    ratio = reported / observed
    assert np.all(ratio > 1 / 1.5) and np.all(ratio < 1.5), (ratio, observed, reported)
    assert reported[0] > 20 * max(reported[1], reported[2]) and observed[0] > 20 * max(observed[1], observed[2])


def test_a_sphere_leaves_its_orientation_open_and_is_not_converged():
    import pyvista as pv

    sphere = pv.Sphere(radius=12.7, theta_resolution=120, phi_resolution=90)
    v, f = np.asarray(sphere.points), np.asarray(sphere.faces).reshape(-1, 4)[:, 1:]
    mesh = prepare_mesh(v, f)
    views = dual_orthogonal_views()
    truth = np.array([2.0, 1.0, -3.0, 0.0, 0.0, 0.0])
    rng = np.random.default_rng(0)
    splines = [OutlineSpline.fit(_noisy_outline(view, v + truth[:3], 0.3, 3.0, rng)) for view in views]
    result = match(MatchProblem(mesh, views, splines), truth + [1, -1, 1, 5, 5, 5], MatchSettings())
    assert result.optimiser_converged and not result.converged
    assert "do not pin the pose down" in result.message
    # the position is sharp; a turn about the mesh's polar axis only shows in its facets
    assert np.all(np.array(result.sd[:3]) < 0.05) and max(result.sd[3:]) > 2.0, result.sd
