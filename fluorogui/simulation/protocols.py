"""The paper's validation protocols (Tables 1–4) as functions over the engine.

- idealized (Tables 1, 2): the model is rendered into a pseudo-fluoroscopic image pair
  at a flexion-like pose in a dual-orthogonal geometry; the images go the normal way
  (Canny, sub-pixel edges, outline, periodic spline) and the pose is matched from ten
  starts perturbed by Gaussian noise within +/-20 mm and +/-20 deg.
- spheres (Table 3): eight 12.70 mm spheres in a vertical zig-zag where neighbours
  touch; each sphere is matched from ten starts and adjacent separations are compared
  with 12.70 mm.
- repeatability (Table 4): ten perturbed starts of a given pose on given outlines.

"Gaussian within +/-R" is read as a normal distribution with SD R/3 truncated at +/-R
(the paper does not give the SD); both are parameters.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from fluorogui.core.matching.loop import (
    fit_splines,
    refine_rims,
    segment_outlines,
    soft_edge_views,
    splines_from_images,
)
from fluorogui.core.matching.matcher import match
from fluorogui.core.matching.problem import MatchProblem, MatchResult, MatchSettings, mask_at
from fluorogui.core.outlines.spline import OutlineSpline
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh, prepare_mesh
from fluorogui.core.projection.pose import (
    angles_from_matrix,
    pose_error,
    rotation_matrix,
    rotvec_matrix,
    transform_points,
)
from fluorogui.core.projection.silhouette import mesh_silhouette, projected_region
from fluorogui.simulation.render import render_fluoro

DOF_LABELS = ("dx", "dy", "dz", "dalpha", "dbeta", "dgamma")
SPHERE_DIAMETER = 12.70


def dual_orthogonal_views(source_to_centre: float = 1000.0, source_to_intensifier: float = 1200.0,
                          image_size=(1024, 1024), pitch: float = 315.0 / 1024.0) -> list[View]:
    """Two views 90 degrees apart looking horizontally at the origin (z up), like the paper's."""
    views = []
    for k, phi in enumerate((-45.0, 45.0)):
        d = np.array([np.cos(np.radians(phi)), np.sin(np.radians(phi)), 0.0])
        views.append(View.looking_at(-source_to_centre * d, [0, 0, 0], [0, 0, 1], source_to_intensifier,
                                     image_size=image_size, pitch=pitch, name=f"view {k + 1}"))
    return views


def two_views(angle_deg: float = 90.0, tilt_deg: float = 0.0, *, offset_px=(0.0, 0.0),
              source_to_centre=(1000.0, 1000.0), source_to_intensifier=(1200.0, 1200.0),
              image_size=(1024, 1024), pitch: float = 315.0 / 1024.0) -> list[View]:
    """Two views ``angle_deg`` apart about the vertical (z) axis, both tilted ``tilt_deg``
    up from horizontal, looking at the origin; ``offset_px`` moves the principal point
    (the object sits off the image centre); source distances may differ per view."""
    views = []
    for k, phi in enumerate((-angle_deg / 2.0, angle_deg / 2.0)):
        tilt = np.radians(tilt_deg) * (1 if k == 0 else -0.5)  # tilted differently: no common plane
        d = np.array([np.cos(np.radians(phi)) * np.cos(tilt), np.sin(np.radians(phi)) * np.cos(tilt), np.sin(tilt)])
        view = View.looking_at(-source_to_centre[k] * d, [0, 0, 0], [0, 0, 1], source_to_intensifier[k],
                               image_size=image_size, pitch=pitch, name=f"view {k + 1}")
        if any(offset_px):
            pp = (view.principal_point[0] + offset_px[0], view.principal_point[1] + offset_px[1])
            view = View(view.source, view.normal, view.e_u, view.e_v, view.distance, view.pitch, pp,
                        view.image_size, view.name)
        views.append(view)
    return views


#: the names ``mesh_variant`` knows
VARIANTS = ("mirrored", "scaled+15", "scaled-15", "ps-box", "symmetric", "symmetric-ap")


def mesh_variant(vertices, faces, variant: str) -> tuple[np.ndarray, np.ndarray]:
    """A variant of a mesh: ``mirrored`` (left knee from right: x -> -x, faces turned),
    ``scaled+15`` / ``scaled-15`` (about its centroid), ``ps-box`` (a femoral component
    made posterior-stabilised: a closed intercondylar box), ``symmetric`` (the medial,
    +x, half mirrored onto the lateral), ``symmetric-ap`` (the anterior half mirrored onto
    the posterior: a tray that looks the same turned 180 deg about its axis), or ``""``
    as it is (``simulation.implant_variants``)."""
    from fluorogui.simulation.implant_variants import mirrored_half, ps_box

    v, f = np.asarray(vertices, dtype=float), np.asarray(faces)
    if not variant:
        return v, f
    if variant == "mirrored":
        return v * [-1.0, 1.0, 1.0], f[:, ::-1].copy()
    if variant.startswith("scaled"):
        factor = 1.0 + float(variant[len("scaled"):]) / 100.0
        c = v.mean(0)
        return c + (v - c) * factor, f
    if variant == "ps-box":
        return ps_box(v, f)
    if variant in ("symmetric", "symmetric-ap"):
        return mirrored_half(v, f, axis=0 if variant == "symmetric" else 1)
    raise ValueError(f"unknown mesh variant {variant!r} ({', '.join(VARIANTS)})")


def perturbed_starts(truth, n: int, rng: np.random.Generator, *, range_mm: float = 20.0,
                     range_deg: float = 20.0, sd_fraction: float = 1.0 / 3.0) -> np.ndarray:
    """``n`` starts: the truth plus truncated Gaussian noise (SD = range * sd_fraction)."""
    truth = np.asarray(truth, dtype=float)
    scale = np.r_[[range_mm] * 3, [range_deg] * 3]
    noise = rng.normal(0.0, 1.0, (n, 6)) * scale * sd_fraction
    while np.any(np.abs(noise) > scale):  # redraw what falls outside the range
        bad = np.abs(noise) > scale
        noise[bad] = (rng.normal(0.0, 1.0, (n, 6)) * scale * sd_fraction)[bad]
    return truth + noise


def longest_axis(vertices) -> int:
    """Index of the model axis with the largest extent (the mediolateral axis of both components)."""
    v = np.asarray(vertices)
    return int(np.argmax(v.max(0) - v.min(0)))


def flexion_pose(vertices, flexion_deg: float) -> np.ndarray:
    """A deep-knee-bend-like pose: flexion about the model's mediolateral axis plus a little
    varus and internal rotation so no view is exactly along a symmetry plane."""
    ml = longest_axis(vertices)
    axes = np.eye(3)
    # rotate about the ML axis by the flexion, then small fixed tilts about the others
    R = rotvec_matrix(np.radians(flexion_deg) * axes[ml])
    R = rotvec_matrix(np.radians(3.0) * axes[(ml + 1) % 3]) @ rotvec_matrix(np.radians(5.0) * axes[(ml + 2) % 3]) @ R
    centroid = np.asarray(vertices, dtype=float).mean(0)
    t = -R @ centroid  # model centroid at the isocentre
    return np.array([*t, *angles_from_matrix(R)])


@dataclass
class Summary:
    """Accuracy (mean), repeatability (sample SD) and RMSE per DOF of convergent runs."""

    mean: np.ndarray
    sd: np.ndarray
    rmse: np.ndarray
    n_runs: int
    n_converged: int
    median_seconds: float
    median_calls: float

    def to_dict(self) -> dict:
        return {"mean": self.mean.tolist(), "sd": self.sd.tolist(), "rmse": self.rmse.tolist(),
                "n_runs": self.n_runs, "n_converged": self.n_converged,
                "median_seconds": self.median_seconds, "median_calls": self.median_calls}


def summarise(errors: np.ndarray, results: list[MatchResult], convergent_only: bool = True) -> Summary:
    errors = np.asarray(errors, dtype=float).reshape(-1, 6)
    conv = np.array([r.converged for r in results], dtype=bool)
    use = errors[conv] if convergent_only and conv.any() else errors
    sd = use.std(0, ddof=1) if len(use) > 1 else np.zeros(6)
    return Summary(use.mean(0), sd, np.sqrt((use ** 2).mean(0)), len(results), int(conv.sum()),
                   float(np.median([r.seconds for r in results])), float(np.median([r.calls for r in results])))


@dataclass
class CaseResult:
    label: str
    truth: np.ndarray
    results: list[MatchResult]
    errors: np.ndarray
    summary: Summary
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"label": self.label, "truth": self.truth.tolist(), "errors": self.errors.tolist(),
                "summary": self.summary.to_dict(), "runs": [r.to_dict() for r in self.results], **self.extra}


def outlines_from_images(images, views, mesh: PreparedMesh, nominal_pose) -> list[OutlineSpline]:
    """The normal image path (Canny, sub-pixel edges, periodic spline), the outline chosen
    along the projection of ``nominal_pose`` (standing in for the user's review)."""
    return splines_from_images(images, views, mesh, nominal_pose)


def run_starts(problem: MatchProblem, truth, starts, settings: MatchSettings,
               *, progress: Callable[[int, int], None] | None = None, cancel=None) -> tuple[list[MatchResult],
                                                                                            np.ndarray]:
    results, errors = [], []
    for k, s in enumerate(starts):
        res = match(problem, s, settings, cancel=cancel)
        results.append(res)
        errors.append(pose_error(res.pose, truth))
        if progress is not None:
            progress(k + 1, len(starts))
    return results, np.array(errors)


#: the polyethylene insert between the femoral condyles and the tibial tray (mm)
INSERT_GAP_MM = 8.0


def other_component_pose(matched_vertices, matched_pose, other_vertices, other_is_tibial: bool,
                         *, flexion_deg: float, gap_mm: float = INSERT_GAP_MM) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of the other component of the knee, world from its model frame, for a matched
    component at ``matched_pose``: the femoral component flexed ``flexion_deg`` about the
    tibial tray's mediolateral (x) axis, centred over the tray, its lowest point
    ``gap_mm`` (the insert) above the tray's top. Both meshes in the component frame (x
    mediolateral, y anterior, z proximal)."""
    femur, tibia = (matched_vertices, other_vertices) if other_is_tibial else (other_vertices, matched_vertices)
    femur, tibia = np.asarray(femur, dtype=float), np.asarray(tibia, dtype=float)
    R_ft = rotvec_matrix(np.radians(flexion_deg) * np.array([1.0, 0.0, 0.0]))  # femur in the tibial frame
    flexed = femur @ R_ft.T
    tray_lo, tray_hi = tibia.min(0), tibia.max(0)
    t_ft = np.r_[(tray_lo[:2] + tray_hi[:2]) / 2.0 - (flexed.min(0)[:2] + flexed.max(0)[:2]) / 2.0,
                 tray_hi[2] + gap_mm - flexed[:, 2].min()]
    R_m, t_m = rotation_matrix(*np.asarray(matched_pose, dtype=float)[3:]), np.asarray(matched_pose, dtype=float)[:3]
    if other_is_tibial:  # tibia = matched femur's frame composed with the inverse of femur-in-tibia
        R = R_m @ R_ft.T
        return R, t_m - R @ t_ft
    return R_m @ R_ft, R_m @ t_ft + t_m


def occlusion_masks(views, mesh: PreparedMesh, R, t, *, margin_px: int = 3) -> list[np.ndarray]:
    """Per view, where a mesh at (R, t) projects, grown by ``margin_px`` (as the knee
    workflow masks the other component at its matched pose)."""
    return [projected_region(view, [(mesh, R, t)], margin_px) for view in views]


def rim_refined_outlines(images, views, mesh: PreparedMesh, plain, *, start, settings: MatchSettings | None = None,
                         occluded=None, mode: str = "on") -> tuple[list, list[int], list]:
    """``plain`` outlines refined for the metal's rim as the automatic loop does: at the pose
    matched from ``start``, twice (the second time at the pose the first refinement gives),
    the image's rim models fitted once and kept; with ``mode`` "auto" only in the views
    whose edge is soft (``pipeline.soft_edge_views``), "off" none. Returns the outlines,
    the views refined and the outlines' point weights (None per view: all alike)."""
    if mode == "off":
        return list(plain), [], [None] * len(plain)
    pose = match(MatchProblem(mesh, views, fit_splines(plain), occluded), start, settings).pose
    only, models = [k for k, p in enumerate(plain) if p is not None], None
    if mode == "auto":
        only, models = soft_edge_views(images, views, mesh, pose, outlines=plain, occluded=occluded)
        if not only:
            return list(plain), [], [None] * len(plain)
    for _ in range(2):
        outlines, models, weights = refine_rims(images, views, mesh, pose, outlines=plain, occluded=occluded,
                                                models=models, only=only)
        pose = match(MatchProblem(mesh, views, fit_splines(outlines, weights), occluded), pose, settings).pose
    return outlines, only, weights


def idealized_case(vertices, faces, flexion_deg: float, settings: MatchSettings, *, n_starts: int = 10,
                   seed: int = 0, views: list[View] | None = None, label: str = "",
                   render: Callable | None = None, other=None, other_is_tibial: bool = True,
                   start_sd_fraction: float = 1.0 / 3.0, rim: str = "auto") -> CaseResult:
    """One row of Table 1/2: render, segment, match from perturbed starts, compare with the truth.

    ``render(view, [(world_vertices, faces)], rng) -> image`` makes the images; the
    default is ``simulation.render.render_fluoro`` (a filled silhouette: the matcher's own model
    of the image, so a bias of that model cancels out); the command line passes the
    independent ``fluorogui.reference.xray`` model.

    ``other`` (vertices, faces) is the knee's other component (``other_is_tibial``: it is
    the tray below a matched femoral component, else the femoral component above a matched
    tray), placed by ``other_component_pose`` and imaged in the same images; its
    projection is masked out of segmentation and matching as the knee workflow does, and
    ``extra["occluded"]`` gives the share of the matched outline it hides per view.
    ``start_sd_fraction``: the starts' Gaussian SD as a fraction of +/-20 mm / 20 deg.
    ``rim``: the rim refinement as the automatic loop's ``LoopSettings.rim`` ("auto":
    in the views with a soft edge); ``extra["rim_refined"]`` lists the views refined."""
    rng = np.random.default_rng(seed)
    views = views or dual_orthogonal_views()
    mesh = prepare_mesh(vertices, faces)
    truth = flexion_pose(vertices, flexion_deg)
    world = transform_points(truth, mesh.vertices)
    bodies, occluded, extra = [(world, mesh.faces)], None, {}
    if other is not None:
        other_mesh = prepare_mesh(*other)
        R, t = other_component_pose(mesh.vertices, truth, other_mesh.vertices, other_is_tibial, flexion_deg=flexion_deg)
        bodies.append((other_mesh.vertices @ R.T + t, other_mesh.faces))
        occluded = occlusion_masks(views, other_mesh, R, t)
        R_m = rotation_matrix(*truth[3:])
        extra["occluded"] = [float(np.mean(mask_at(m, mesh_silhouette(mesh, R_m, truth[:3], v).points_px)))
                             for m, v in zip(occluded, views)]
    images = [(render or render_fluoro)(v, bodies, rng) for v in views]
    outlines = segment_outlines(images, views, mesh, truth, occluded=occluded)
    starts = perturbed_starts(truth, n_starts, rng, sd_fraction=start_sd_fraction)
    outlines, extra["rim_refined"], weights = rim_refined_outlines(images, views, mesh, outlines, start=starts[0],
                                                                   settings=settings,
                                                                   occluded=occluded, mode=rim)
    problem = MatchProblem(mesh, views, fit_splines(outlines, weights), occluded)
    results, errors = run_starts(problem, truth, starts, settings)
    return CaseResult(label or f"{flexion_deg:g} deg", truth, results, errors, summarise(errors, results), extra)


def sphere_centres(n: int = 8, diameter: float = SPHERE_DIAMETER) -> np.ndarray:
    """Centres of ``n`` touching spheres zig-zagging upwards in a vertical plane."""
    step_x, step_z = diameter * np.cos(np.radians(60.0)), diameter * np.sin(np.radians(60.0))
    k = np.arange(n)
    x = (k % 2) * step_x - step_x / 2.0
    return np.column_stack([x, np.zeros(n), k * step_z - (n - 1) * step_z / 2.0])


def spheres_case(sphere_vertices, sphere_faces, settings: MatchSettings, *, n_starts: int = 10,
                 seed: int = 0, views: list[View] | None = None) -> dict:
    """Table 3: match every sphere from perturbed starts, report adjacent separations.

    Each sphere is rendered in an image pair of its own (no occlusion by its neighbours;
    the real test had some), so the test isolates segmentation and geometry.
    """
    rng = np.random.default_rng(seed)
    views = views or dual_orthogonal_views()
    mesh = prepare_mesh(sphere_vertices, sphere_faces)
    centres = sphere_centres()
    found = np.zeros((n_starts, len(centres), 3))
    all_results = []
    for i, c in enumerate(centres):
        truth = np.array([*(c - mesh.centroid), 0.0, 0.0, 0.0])
        world = transform_points(truth, mesh.vertices)
        images = [render_fluoro(v, [(world, mesh.faces)], rng) for v in views]
        problem = MatchProblem(mesh, views, outlines_from_images(images, views, mesh, truth))
        starts = perturbed_starts(truth, n_starts, rng, range_deg=0.0)
        results, _ = run_starts(problem, truth, starts, settings)
        all_results.extend(results)
        for k, r in enumerate(results):
            found[k, i] = transform_points(r.pose, mesh.centroid[None, :])[0]
    separations = np.linalg.norm(np.diff(found, axis=1), axis=2)  # (starts, pairs)
    pair_mean = separations.mean(0)
    return {
        "pairs": [f"{i + 1} to {i + 2}" for i in range(len(centres) - 1)],
        "pair_mean_mm": pair_mean.tolist(),
        "pair_sd_mm": separations.std(0, ddof=1).tolist(),
        "pair_rmse_mm": np.sqrt(((separations - SPHERE_DIAMETER) ** 2).mean(0)).tolist(),
        "mean_mm": float(separations.mean()),
        "mean_error_mm": float(separations.mean() - SPHERE_DIAMETER),
        "sd_mm": float(separations.std(ddof=1)),
        "rmse_mm": float(np.sqrt(((separations - SPHERE_DIAMETER) ** 2).mean())),
        "converged": int(sum(r.converged for r in all_results)),
        "runs": len(all_results),
        "median_seconds": float(np.median([r.seconds for r in all_results])),
    }


def repeatability_case(problem: MatchProblem, pose, settings: MatchSettings, *, n_starts: int = 10,
                       seed: int = 0, label: str = "") -> CaseResult:
    """Table 4: spread of the matched pose over perturbed starts of a given pose.

    Errors are taken against the mean of the convergent matches (no ground truth)."""
    rng = np.random.default_rng(seed)
    pose = np.asarray(pose, dtype=float)
    results, errors = run_starts(problem, pose, perturbed_starts(pose, n_starts, rng), settings)
    conv = np.array([r.converged for r in results])
    centre = errors[conv].mean(0) if conv.any() else errors.mean(0)
    spread = errors - centre
    summary = summarise(spread, results)
    return CaseResult(label, pose, results, spread, summary,
                      {"per_view_mean_mm": np.mean([r.per_view_mean_mm for r in results], axis=0).tolist()})
