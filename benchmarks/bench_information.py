"""How precisely could any method find the pose from the X-ray model's images?

    python benchmarks/bench_information.py --xray MESH [--flexion 30 60] [--tilted] [--single-view] [--photons 3000]

The Cramer-Rao bound: the smallest standard deviation an unbiased estimator of the six
pose variables can have, given the images' quantum noise. It is computed from the image
model alone (``fluorogui.reference.xray``, noise-free transmitted fractions ``T`` per
pixel), never from the matcher: the Fisher information of Poisson counts of ``photons T``
per pixel is ``photons * sum_pixels dT/dp_i dT/dp_j / T``, the derivatives by central
differences of the rendered images over the pose variables (mm, degrees). The bound
treats the attenuation, the blur and the background as known, so a real method, which
must also estimate them, can only do worse.

Beside ``benchmarks/bench_uncertainty.py --xray`` (the matcher's observed spread over noise
draws) it says how much of the spread the images themselves force and how much the
method adds, and whether a target such as 0.01 deg mean error can be reached at this
noise level at all.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from fluorogui.core.projection.mesh import prepare_mesh
from fluorogui.core.projection.pose import transform_points
from fluorogui.io.meshes.read import load_mesh
from fluorogui.reference.xray import MU_METAL, Body, XrayModel, line_integrals
from fluorogui.simulation.protocols import dual_orthogonal_views, flexion_pose, two_views

NAMES = ("x", "y", "z", "alpha", "beta", "gamma")
#: central-difference step (mm, degrees): the silhouette moves about 0.05-0.1 px (0.02
#: gave the same bound to within 0.0001 for the femur at 60 deg)
STEP = 0.05


def fisher_information(views, mesh, pose, model: XrayModel) -> np.ndarray:
    """Fisher information (6x6) of the pose variables from all views' images."""
    info = np.zeros((6, 6))
    pose = np.asarray(pose, dtype=float)

    def transmitted(view, p):
        return line_integrals(view, [Body(transform_points(p, mesh.vertices), mesh.faces, MU_METAL)], model)

    for view in views:
        centre = transmitted(view, pose)
        grads = []
        for j in range(6):
            d = np.zeros(6)
            d[j] = STEP
            grads.append(((transmitted(view, pose + d) - transmitted(view, pose - d)) / (2 * STEP)).ravel())
        G = np.asarray(grads)  # (6, pixels)
        weight = model.photons / np.maximum(centre.ravel(), 1e-12)
        changed = np.any(G != 0, axis=0)
        info += (G[:, changed] * weight[changed]) @ G[:, changed].T
    return info


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--xray", metavar="MESH", required=True, help="the component's mesh (STL/OBJ/PLY)")
    p.add_argument("--flexion", type=float, nargs="+", default=[30.0, 60.0])
    p.add_argument("--tilted", action="store_true",
                   help="the protocol's tilted geometry (views 60 deg apart, tilt 10, offset 40 -30, "
                        "source 900 / 1100 mm) instead of two orthogonal views")
    p.add_argument("--single-view", action="store_true", help="the first view only")
    p.add_argument("--photons", type=float, default=XrayModel().photons, help="counts per pixel of air")
    args = p.parse_args()
    if not args.photons or args.photons <= 0:
        p.error("--photons: give a positive count (without noise the bound is zero)")
    mesh = prepare_mesh(*load_mesh(args.xray))
    views = (two_views(60.0, 10.0, offset_px=(40.0, -30.0), source_to_centre=(900.0, 1100.0)) if args.tilted
             else dual_orthogonal_views())
    views = views[:1] if args.single_view else views
    model = XrayModel(photons=args.photons)
    print("Cramer-Rao bound of the pose SD (mm, deg) on X-ray model images, "
          f"{args.xray.split('/')[-1]}, {'tilted' if args.tilted else 'orthogonal'} views"
          f"{' (the first only)' if args.single_view else ''}, "
          f"{args.photons:g} photons per pixel of air")
    print(f"  {'':<10}" + "".join(f"{d:>9}" for d in NAMES) + "  time")
    for flexion in args.flexion:
        t0 = time.perf_counter()
        info = fisher_information(views, mesh, flexion_pose(mesh.vertices, flexion), model)
        cov = np.linalg.inv(info)
        bound = np.sqrt(np.diag(cov))
        line = f"  {flexion:>6g} deg" + "".join(f"{v:>9.4f}" for v in bound) + f"  {time.perf_counter() - t0:.0f} s"
        if args.single_view:  # translation along the beam, and across it (the two others)
            beam = np.asarray(views[0].normal, dtype=float)
            across = np.linalg.svd(beam[None, :])[2][1:]
            line += (f"; along the beam {np.sqrt(beam @ cov[:3, :3] @ beam):.4f} mm, across it "
                     + " / ".join(f"{np.sqrt(a @ cov[:3, :3] @ a):.4f}" for a in across))
        print(line)


if __name__ == "__main__":
    main()
