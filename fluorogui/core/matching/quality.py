"""Quality checks of a matched pose, so that a converged wrong pose is never shown as matched.

A match can converge in a false minimum with a small residual: the image outline was
segmented along the (wrong) prediction, so it follows the model where it should not.
The checks here look at the result from several sides:

* ``per_view_mean_mm``: the matcher's mean outline distance per view, judged against an
  absolute ceiling and against the sequence's typical residual;
* ``edge_support``: the share of the projected model outline (visible parts) that lies
  within ``tol_px`` of an image edge in a Canny map made independently of the outline
  that was matched (with low thresholds, so a faint keel still counts);
* ``outline_support``: the share of the image outline lying within ``tol_px`` of the
  projected model outline (a chord across a gap, or a piece of another edge, shows here);
* ``jump``: how far the result lies from the predicted pose (centroid mm and rotation
  degrees), against what the motion so far makes plausible.

``judge`` turns these into a status, ``matched`` or ``needs_review``, and a reason in
plain words. A view whose edges alone are weak (``weak_view``: its edge support is the only
check that fails) is a view, not a verdict: ``weak_view_problem`` judges the pose by what
the other views pin down alone, and names the direction they leave loose. ``check_match``
is the matcher's own verdict on a single result, from what
the match itself holds (residual per view, outline coverage both ways, the pose's
standard deviations), applied to every match. Pure numpy / OpenCV.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Sequence

import cv2
import numpy as np
from scipy.spatial import cKDTree

from fluorogui.core.matching.problem import mask_at, visible_points
from fluorogui.core.outlines.edges import canny_edges
from fluorogui.core.outlines.spline import resample_closed_polyline
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.projection.pose import motion_between, rotation_matrix
from fluorogui.core.projection.silhouette import mesh_silhouette
from fluorogui.core.status import Status

#: the thresholds that are shares of an outline (0 to 1)
SHARE_THRESHOLDS = frozenset({"min_edge_support", "min_outline_support", "max_outside_field", "min_visible_share"})


@dataclass
class QualityThresholds:
    """Limits a matched frame must meet; the defaults come from the real biplane data
    (right poses: 0.11-0.21 mm per view, edge support >= 0.9) and the demo."""

    max_view_mm: float = 0.6  # a view's mean outline distance above this always fails
    floor_view_mm: float = 0.25  # ... and below this passes while the typical residual is unknown
    typical_factor: float = 3.0  # with a typical residual: fails above factor x typical
    typical_margin_mm: float = 0.05  # ... or above typical + margin, whichever is larger
    min_edge_support: float = 0.85
    min_outline_support: float = 0.85
    # a component partly beyond the field of view (or an image's edge) is matched and judged on
    # what is visible: it passes while its pose stays pinned down (SD within these; on a
    # generated bend the tray stayed within 0.011 mm / 0.04 deg with SDs <= 0.03 deg down to
    # 45 % visible) and at least this share of its outline is visible in every view
    max_outside_field: float = 0.02  # share beyond the field of view taken as fully visible
    min_visible_share: float = 0.35
    partial_sd_mm: float = 0.25
    partial_sd_deg: float = 0.25
    tol_px: float = 1.5
    max_jump_mm: float = 15.0  # centroid distance from the prediction
    max_jump_deg: float = 25.0
    max_sd_mm: float = 2.0  # a pose whose outlines leave a translation this uncertain (1 SD) fails
    max_sd_deg: float = 2.0  # ... or a rotation
    single_view_depth_factor: float = 10.0  # one view: the translation along the beam may be this much looser

    def __post_init__(self):
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise ValueError(f"quality threshold {name} must be a finite number of 0 or more, not {value!r}")
            if name in SHARE_THRESHOLDS and value > 1:
                raise ValueError(f"quality threshold {name} is a share: 0 to 1, not {value!r}")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict | None) -> "QualityThresholds":
        d = d or {}
        return cls(**{k: float(d[k]) for k in cls.__dataclass_fields__ if k in d})


@dataclass
class Quality:
    """Measured quality of one component's pose in one frame."""

    converged: bool
    per_view_mean_mm: list[float]
    edge_support: list[float] = field(default_factory=list)
    outline_support: list[float] = field(default_factory=list)
    jump_mm: float = 0.0
    jump_deg: float = 0.0
    outside_field: list[float] = field(default_factory=list)  # share of the outline off the field of view
    sd: list[float] | None = None  # the pose's standard deviations (mm, deg; the Euler angles')
    # the body's own: its centroid (world mm) and its turn about the model's axes (deg), free of
    # the Euler angles' coupling (``MatchResult.sd_body``); what the partly visible rule judges
    sd_body: list[float] | None = None

    def to_dict(self) -> dict:
        d = asdict(self)
        out = {k: (round(v, 5) if isinstance(v, float) else [round(x, 5) for x in v] if isinstance(v, list) else v)
               for k, v in d.items()}
        for key in ("sd", "sd_body"):  # an SD the outlines leave undetermined: None (JSON has no infinity)
            if out[key] is not None:
                out[key] = [v if np.isfinite(v) else None for v in out[key]]
        return out


def model_outline(mesh: PreparedMesh, pose, view: View, spacing_px: float = 2.0) -> np.ndarray:
    pose = np.asarray(pose, dtype=float)
    sil = mesh_silhouette(mesh, rotation_matrix(*pose[3:]), pose[:3], view, spacing_px=spacing_px)
    return sil.points_px


def edge_support(image: np.ndarray, outline_px: np.ndarray, *, occluded: np.ndarray | None = None,
                 tol_px: float = 1.5, thresholds: tuple[float, float] = (0.04, 0.12), sigma: float = 1.0) -> float:
    """Share of the (visible) outline points lying within ``tol_px`` of a Canny edge of
    ``image``, with Canny run on a crop around the outline."""
    _, near = edge_supported_points(image, outline_px, occluded=occluded, tol_px=tol_px, thresholds=thresholds,
                                    sigma=sigma)
    return float(np.mean(near)) if len(near) else 0.0


def edge_supported_points(image: np.ndarray, outline_px: np.ndarray, *, occluded: np.ndarray | None = None,
                          tol_px: float = 1.5, thresholds: tuple[float, float] = (0.04, 0.12),
                          sigma: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The (visible) outline points and, per point, whether it lies within ``tol_px`` of a
    Canny edge of ``image`` (``edge_support`` is their share)."""
    pts = np.asarray(outline_px, dtype=float)
    pts = pts[visible_points(occluded, pts)]
    none = np.zeros(len(pts), dtype=bool)
    if len(pts) == 0:
        return pts, none
    h, w = np.asarray(image).shape[:2]
    pad = 12
    u0, v0 = max(int(pts[:, 0].min()) - pad, 0), max(int(pts[:, 1].min()) - pad, 0)
    u1, v1 = min(int(pts[:, 0].max()) + pad + 1, w), min(int(pts[:, 1].max()) + pad + 1, h)
    if u1 - u0 < 4 or v1 - v0 < 4:
        return pts, none
    crop = np.asarray(image, dtype=np.float32)[v0:v1, u0:u1]
    edges = canny_edges(crop, thresholds[0], thresholds[1], sigma)
    local = pts - (u0, v0)
    inside = (local[:, 0] >= 0) & (local[:, 0] < u1 - u0) & (local[:, 1] >= 0) & (local[:, 1] < v1 - v0)
    col = np.clip(np.round(local[:, 0]).astype(int), 0, u1 - u0 - 1)
    row = np.clip(np.round(local[:, 1]).astype(int), 0, v1 - v0 - 1)
    return pts, _near_edges(edges, row, col, tol_px) & inside


#: OpenCV's 5x5 L2 chamfer distance (``cv2.distanceTransform(..., cv2.DIST_L2, 5)``) is 0 on an
#: edge, 1 beside one, 1.4 (1.400009 in its fixed point) diagonally and at least 2 beyond:
#: for tolerances in this range "within tolerance" is "an edge pixel among the 3 x 3"
NEIGHBOURHOOD_TOLERANCES = (1.41, 2.0)


def _near_edges(edges: np.ndarray, row: np.ndarray, col: np.ndarray, tol_px: float) -> np.ndarray:
    """Per pixel (row, col) of the boolean edge map, whether its chamfer distance to an edge
    pixel is at most ``tol_px``: the 3 x 3 look-up where that is the same (the usual 1.5 px,
    ~20x cheaper than the whole crop's distance transform), else the distance transform."""
    if not NEIGHBOURHOOD_TOLERANCES[0] <= tol_px < NEIGHBOURHOOD_TOLERANCES[1]:
        distance = cv2.distanceTransform((~edges).astype(np.uint8), cv2.DIST_L2, 5)
        return distance[row, col] <= tol_px
    padded = np.zeros((edges.shape[0] + 2, edges.shape[1] + 2), dtype=bool)  # nothing beyond the crop
    padded[1:-1, 1:-1] = edges
    near = np.zeros(len(row), dtype=bool)
    for dr in (0, 1, 2):
        for dc in (0, 1, 2):
            near |= padded[row + dr, col + dc]
    return near


def hidden_where_no_edges(image: np.ndarray, model_outline_px: np.ndarray, hidden: np.ndarray | None, *,
                          tol_px: float = 1.5) -> np.ndarray:
    """``hidden`` (a view's boolean mask, or None) grown by the stretches of the model
    outline that lie on no image edge (``edge_supported_points``), each point's disc of
    twice ``tol_px``: what is left of the view's outline is what its edges show."""
    mask = np.zeros(np.asarray(image).shape[:2], bool) if hidden is None else np.array(hidden, dtype=bool)
    points, on_edge = edge_supported_points(image, model_outline_px, occluded=hidden, tol_px=tol_px)
    reach = int(np.ceil(2 * tol_px))
    canvas = np.zeros(mask.shape, np.uint8)
    for u, v in np.round(points[~on_edge]).astype(int):
        cv2.circle(canvas, (int(u), int(v)), reach, 1, -1)
    return mask | canvas.astype(bool)


def outline_support(image_outline_px: np.ndarray, model_outline_px: np.ndarray, occluded: np.ndarray | None = None,
                    tol_px: float = 1.5) -> float:
    """Share of the (visible) image outline points - dense samples along the traced edges,
    without the chords the outline draws across gaps - lying within ``tol_px`` of the
    model outline."""
    image_pts = np.asarray(image_outline_px, dtype=float).reshape(-1, 2)
    image_pts = image_pts[visible_points(occluded, image_pts)]
    model = resample_closed_polyline(np.asarray(model_outline_px, dtype=float), spacing=0.5)
    if len(image_pts) == 0 or len(model) == 0:
        return 0.0
    # only the distances count, never which point gives them: the unbalanced tree (quicker
    # to build, ~15 % in all here) finds the same nearest distance
    d, _ = cKDTree(model, balanced_tree=False).query(image_pts)
    return float(np.mean(d <= tol_px))


def outside_share(field_mask: np.ndarray, points_px: np.ndarray) -> float:
    """Share of points (K, 2) off the field of view (off the image counts as off)."""
    pts = np.asarray(points_px, dtype=float).reshape(-1, 2)
    return float(1.0 - mask_at(field_mask, pts).mean()) if len(pts) else 0.0


def pose_jump(mesh: PreparedMesh, pose, predicted) -> tuple[float, float]:
    """Distance (mm) between the model centroids and rotation angle (deg) between two poses."""
    return motion_between(pose, predicted, mesh.centroid)


def assess(images: Sequence[np.ndarray], views: Sequence[View], mesh: PreparedMesh, pose, *, converged: bool,
           per_view_mean_mm: Sequence[float], image_outlines: Sequence[np.ndarray] | None,
           predicted=None, occluded: Sequence | None = None, tol_px: float = 1.5,
           fields: Sequence[np.ndarray] | None = None, model_outlines: Sequence[np.ndarray] | None = None,
           sd: Sequence[float] | None = None, sd_body: Sequence[float] | None = None) -> Quality:
    """Every check of a pose. ``image_outlines`` are the outlines it was matched to (dense
    points per view, chords left out; None skips ``outline_support``); ``fields`` are the
    intensifiers' fields of view (bool images): an outline reaching beyond one is cut off
    by the rim, whose edge is not the implant's. ``model_outlines`` (per view, the model
    outline at ``pose``, e.g. the matcher's last) saves projecting the model again."""
    edge, support, outside = [], [], []
    for k, (image, view) in enumerate(zip(images, views)):
        mask = occluded[k] if occluded is not None and k < len(occluded) else None
        model = model_outlines[k] if model_outlines is not None else model_outline(mesh, pose, view)
        edge.append(edge_support(image, model, occluded=mask, tol_px=tol_px))
        if image_outlines is not None:
            support.append(outline_support(image_outlines[k], model, mask, tol_px))
        if fields is not None and k < len(fields) and fields[k] is not None:
            outside.append(outside_share(fields[k], model))
    jump = pose_jump(mesh, pose, predicted) if predicted is not None else (0.0, 0.0)
    return Quality(bool(converged), [float(v) for v in per_view_mean_mm], edge, support, *jump, outside,
                   None if sd is None else [float(v) for v in sd],
                   None if sd_body is None else [float(v) for v in sd_body])


#: the checks ``match_checks`` applies to a match's own evidence, by name
MATCH_CHECKS = ("residual", "model_on_outline", "outline_on_model", "uncertainty")


def check_match(problem, result, thresholds: QualityThresholds | None = None) -> list[str]:
    """What a match's own evidence says against it, in plain words (empty: nothing): the
    texts of ``match_checks``."""
    return [text for _, text in match_checks(problem, result, thresholds)]


def match_checks(problem, result, thresholds: QualityThresholds | None = None) -> list[tuple[str, str]]:
    """The checks (``MATCH_CHECKS``) a match's own evidence fails, each with its reason in
    plain words (empty: none).

    ``problem`` is the ``MatchProblem`` it was matched on, ``result`` its ``MatchResult``
    (with ``outlines_px``, the model outline at the result, and ``sd_body``, else ``sd``). Checks, per view:
    the mean outline distance against the absolute ceiling ``max_view_mm`` (the
    sequence-relative limits are ``judge``'s); the share of the model outline lying on
    the image outline and of the image outline lying on the model (both ways, so neither
    can slide onto part of the other); and the uncertainty the outlines leave (the
    Gauss-Newton matrix's conditioning, as standard deviations of the body's centroid and
    of its turn about its axes, against
    ``max_sd_mm`` / ``max_sd_deg``, each named where it is exceeded)."""
    t = thresholds or QualityThresholds()
    problems = []
    names = [v.name or f"view {k + 1}" for k, v in enumerate(problem.views)]
    for name, value in zip(names, result.per_view_mean_mm):
        if not np.isfinite(value) or value > t.max_view_mm:
            problems.append(("residual", f"outline distance {value:.2f} mm in {name} (limit {t.max_view_mm:.2f} mm)"))
    model_outlines = result.outlines_px or []
    for k, (name, spline, model) in enumerate(zip(names, problem.splines, model_outlines)):
        mask = problem.occluder(k)
        model = np.asarray(model, dtype=float).reshape(-1, 2)
        pts = model[visible_points(mask, model)]
        if len(pts) < 3:
            problems.append(("model_on_outline", f"the model outline is not visible in {name}"))
            continue
        dist, _, _, t_near = spline.closest(pts)
        measured = ~spline.in_gap(t_near) if len(spline.gaps) else np.ones(len(pts), dtype=bool)
        on_image = float(np.mean(dist[measured] <= t.tol_px)) if measured.any() else 0.0
        if on_image < t.min_edge_support:
            problems.append(("model_on_outline",
                             f"only {100 * on_image:.0f} % of the model outline lies on the image outline in {name}"))
        image = spline.sample(max(64, int(spline.length_px)), skip_gaps=True)
        on_model = outline_support(image, model, mask, t.tol_px)
        if on_model < t.min_outline_support:
            problems.append(("outline_on_model",
                             f"only {100 * on_model:.0f} % of the image outline lies on the model in {name}"))
    # the body's own uncertainty where the match gave it: the Euler angles' SDs add their
    # coupling (near gimbal lock without bound), which is no looseness of the pose
    sd, labels, unit = result.sd_body, ("x", "y", "z", "turn about x", "turn about y", "turn about z"), "deg"
    if sd is None:
        sd, labels = result.sd, ("x", "y", "z", "alpha", "beta", "gamma")
    if sd is not None:
        sd = np.asarray(sd, dtype=float)
        limits = np.array([t.max_sd_mm] * 3 + [t.max_sd_deg] * 3)
        limit_names = ["max_sd_mm"] * 3 + ["max_sd_deg"] * 3
        if len(problem.views) == 1:  # single plane: depth along the beam is weak by nature (stated, not failed)
            depth = int(np.argmax(np.abs(problem.views[0].normal)))
            limits[depth] *= t.single_view_depth_factor
            limit_names[depth] = "max_sd_mm x single_view_depth_factor"
        loose = [j for j in range(6) if not np.isfinite(sd[j]) or sd[j] > limits[j]]
        if loose:
            problems.append(("uncertainty", "the outlines do not pin the pose down (SD " + ", ".join(
                f"{labels[j]} {sd[j]:.2g} {'mm' if j < 3 else unit} over {limit_names[j]} {limits[j]:.2g}"
                for j in loose) + ")"))
    return problems


def judge(quality: Quality, thresholds: QualityThresholds | None = None,
          typical_view_mm: float | None = None, view_names: Sequence[str] | None = None) -> tuple[str, str]:
    """(status, reason): ``matched`` with an empty reason when every check passes, else
    ``needs_review`` with every failed check in plain words."""
    problems = failed_checks(quality, thresholds=thresholds, typical_view_mm=typical_view_mm, view_names=view_names)
    return (Status.NEEDS_REVIEW, "; ".join(text for _, text in problems)) if problems else (Status.MATCHED, "")


#: the checks ``judge`` applies, by the name ``failed_checks`` gives them
CHECKS = ("converged", "residual", "edge_support", "outline_support", "visible", "jump")


def failed_checks(quality: Quality, *, thresholds: QualityThresholds | None = None,
                  typical_view_mm: float | None = None, view_names: Sequence[str] | None = None,
                  why_not_converged: str = "") -> list[tuple[str, str]]:
    """The checks (``CHECKS``) a pose fails, each with its reason in plain words (empty:
    none); what ``judge`` reports, and what a measurement of each check's precision counts.
    ``why_not_converged``: the match's own message (``MatchResult.message``: what
    ``check_match`` found, or how the optimiser stopped), said instead of "did not converge"."""
    t = thresholds or QualityThresholds()
    names = list(view_names or [f"view {k + 1}" for k in range(len(quality.per_view_mean_mm))])
    problems = []
    if not quality.converged:
        problems.append(("converged", why_not_converged or "the match did not converge"))
    limit = min(t.max_view_mm, t.floor_view_mm)
    if typical_view_mm is not None and np.isfinite(typical_view_mm):
        limit = min(t.max_view_mm, max(t.typical_factor * typical_view_mm, typical_view_mm + t.typical_margin_mm))
    for name, value in zip(names, quality.per_view_mean_mm):
        if not np.isfinite(value) or value > limit:
            typical = f", typical {typical_view_mm:.2f} mm" if typical_view_mm else ""
            problems.append(("residual", f"outline distance {value:.2f} mm in {name} (limit {limit:.2f} mm{typical})"))
    for name, value in zip(names, quality.edge_support):
        if value < t.min_edge_support:
            problems.append(("edge_support", f"only {100 * value:.0f} % of the model outline lies on image edges "
                                             f"in {name}"))
    for name, value in zip(names, quality.outline_support):
        if value < t.min_outline_support:
            problems.append(("outline_support", f"only {100 * value:.0f} % of the image outline lies on the model "
                                                f"in {name}"))
    problems += [("visible", text) for text in _partly_visible(quality, t, names)]
    if quality.jump_mm > t.max_jump_mm or quality.jump_deg > t.max_jump_deg:
        problems.append(("jump", f"moved {quality.jump_mm:.1f} mm / {quality.jump_deg:.1f}° from the predicted pose"))
    return problems


_POSE_WORDS = ("translation along x", "translation along y", "translation along z",
               "rotation about the model's x axis (alpha)", "rotation about the model's y axis (beta)",
               "rotation about the model's z axis (gamma)")
#: the same for the body's own motion (``MatchResult.sd_body``): its centroid, its turn about its axes
_BODY_WORDS = ("position along x", "position along y", "position along z", "turn about the model's x axis",
               "turn about the model's y axis", "turn about the model's z axis")


def weak_view(problems: Sequence[tuple[str, str]], quality: Quality,
              thresholds: QualityThresholds | None = None) -> int | None:
    """The index of the one view whose edges are weak, when that is all that fails: edge
    support below the limit there and only there, every other check passed (so the pose
    fits its outlines in every view and the other views' edges carry it); else None."""
    t = thresholds or QualityThresholds()
    if not problems or any(name != "edge_support" for name, _ in problems) or len(quality.edge_support) < 2:
        return None
    weak = [k for k, value in enumerate(quality.edge_support) if value < t.min_edge_support]
    return weak[0] if len(weak) == 1 else None


def weak_view_problem(weak: int, views: Sequence[View], centroid_cov: np.ndarray, sd_body: Sequence[float],
                      *, edge: float, thresholds: QualityThresholds | None = None) -> str:
    """Judge a pose whose view ``weak`` has weak edges by the other views and by the
    stretches of the weak view's outline that do lie on image edges: ``centroid_cov``
    (3 x 3, world mm^2) and ``sd_body`` (the turn about the model's axes, deg, last three
    used) are the pose's uncertainty from those outlines. Empty when they pin it down
    (within ``partial_sd_mm`` / ``partial_sd_deg``, the limits of a partly visible
    component); else why not, naming the loosest direction (a translation along a view's
    beam, which that view cannot see, or a turn)."""
    t = thresholds or QualityThresholds()
    names = [f"view {k + 1}" for k in range(len(views))]
    C = np.asarray(centroid_cov, dtype=float)
    loose = []  # (SD over its limit, words, SD, unit)
    for k, view in enumerate(views):
        n = np.asarray(view.normal, dtype=float)
        var = float(n @ C @ n) if np.all(np.isfinite(C)) else np.inf
        sd = float(np.sqrt(var)) if np.isfinite(var) and var >= 0 else np.inf
        loose.append((sd / t.partial_sd_mm, f"depth along {names[k]}'s axis", sd, "mm"))
    for j, sd in enumerate(np.asarray(sd_body, dtype=float)[3:]):
        sd = float(sd) if np.isfinite(sd) else np.inf
        loose.append((sd / t.partial_sd_deg, _BODY_WORDS[3 + j], sd, "°"))
    ratio, words, sd, unit = max(loose, key=lambda x: x[0])
    if ratio <= 1.0:
        return ""
    amount = f"uncertain to ±{sd:.2g} {unit}" if np.isfinite(sd) else "not determined"
    by = "view" if len(views) == 2 else "views"
    return (f"{names[weak]} has little edge contrast (only {100 * edge:.0f} % of the model outline lies on image "
            f"edges there); judged by the other {by} and the edges {names[weak]} has, its {words} is {amount}")


def _partly_visible(quality: Quality, t: QualityThresholds, names: Sequence[str]) -> list[str]:
    """A component partly beyond the field of view was matched and checked on what is
    visible; it fails only when too little is left, or when that leaves its pose loose
    (said from the pose's own uncertainty, naming the loosest direction). The uncertainty
    is the body's own (its centroid, its turn about its axes) where the match gave it: the
    Euler angles' SDs add their coupling, which is no looseness of the pose (the real
    femur: alpha and beta 0.4-1.4 deg in every frame, its turns 0.07-0.21 deg)."""
    partial = [(value, name) for name, value in zip(names, quality.outside_field) if value > t.max_outside_field]
    if not partial:
        return []
    outside, name = max(partial)
    visible = 1.0 - outside
    where = f"only {100 * visible:.0f} % of the model outline is visible in {name}"
    loosest = ""
    sd, words = (quality.sd_body, _BODY_WORDS) if quality.sd_body is not None else (quality.sd, _POSE_WORDS)
    if sd is not None and len(sd) == 6:
        sd = np.array([np.inf if v is None else v for v in sd], dtype=float)
        limits = np.array([t.partial_sd_mm] * 3 + [t.partial_sd_deg] * 3)
        j = int(np.argmax(np.where(np.isfinite(sd), sd / limits, np.inf)))
        loosest = f"; its {words[j]} is uncertain to ±{sd[j]:.2g} {'mm' if j < 3 else '°'}"
        if not np.isfinite(sd[j]) or sd[j] > limits[j]:
            return [where + loosest]
    if visible < t.min_visible_share:
        return [where + (loosest or "") + f" (at least {100 * t.min_visible_share:.0f} % is needed)"]
    return []
