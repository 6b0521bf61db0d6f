"""Does the reported per-pose SD match the spread over noise realisations?

    python packaging/bench_uncertainty.py [--realisations 100] [--noise 0.1] [--corr 3]

For each scene (a bent ellipsoid, outlines made without the matcher's code by
``fluorogui.validation.outlines``) the matcher is run on many noise realisations; the
table gives, per pose variable, the observed SD of the matched poses, the median reported
SD, their ratio, and the ratio the SD would have if every outline point were counted as
an independent sample (``cluster_px`` ~ 0).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from fluorogui.core.geometry import View
from fluorogui.core.matching import MatchProblem, MatchSettings, match, pose_covariance, pose_sd
from fluorogui.core.mesh import prepare_mesh
from fluorogui.core.pose import pose_difference, rotation_matrix
from fluorogui.core.spline import OutlineSpline
from fluorogui.core.validation import dual_orthogonal_views
from fluorogui.validation.outlines import bent_ellipsoid, noisy_hull_outline

TRUTH = np.array([3.0, -2.0, 5.0, 20.0, -15.0, 30.0])


def scene(name, views, start_sd, args, mesh, world):
    rng = np.random.default_rng(args.seed)
    errors, reported, naive = [], [], []
    t0 = time.perf_counter()
    for _ in range(args.realisations):
        splines = [OutlineSpline.fit(noisy_hull_outline(v, world, args.noise, args.corr, rng)) for v in views]
        problem = MatchProblem(mesh, views, splines)
        result = match(problem, TRUTH + rng.normal(0, start_sd, 6), MatchSettings())
        errors.append(pose_difference(result.pose, TRUTH))
        reported.append(result.sd)
        naive.append(pose_sd(pose_covariance(problem, result.pose, cluster_px=1e-6)))
    observed = np.std(errors, axis=0, ddof=1)
    rep, nai = np.median(reported, axis=0), np.median(naive, axis=0)
    print(f"{name} ({args.realisations} realisations, starts SD {start_sd:g} mm/deg, {time.perf_counter() - t0:.0f} s)")
    print(f"  {'':<18}" + "".join(f"{d:>9}" for d in ("x", "y", "z", "alpha", "beta", "gamma")))
    for label, row in (("observed SD", observed), ("reported SD", rep), ("reported/observed", rep / observed),
                       ("independent/obs.", nai / observed)):
        print(f"  {label:<18}" + "".join(f"{v:>9.4f}" for v in row))
    print()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--realisations", type=int, default=100)
    p.add_argument("--noise", type=float, default=0.1, help="outline noise SD (px)")
    p.add_argument("--corr", type=float, default=3.0, help="noise correlation along the outline (px, Gaussian sigma)")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    v, f = bent_ellipsoid()
    mesh = prepare_mesh(v, f)
    world = v @ rotation_matrix(*TRUTH[3:]).T + TRUTH[:3]
    single = View.looking_at([-1000.0, 0, 0], [0, 0, 0], [0, 0, 1], 1200.0, (1024, 1024), 315 / 1024, name="single")
    scene("biplane, perturbed starts", dual_orthogonal_views(), 0.5, args, mesh, world)
    scene("single view (x out of plane), start at the truth", [single], 0.0, args, mesh, world)
    scene("single view, perturbed starts", [single], 0.5, args, mesh, world)


if __name__ == "__main__":
    main()
