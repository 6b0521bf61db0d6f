"""Reference poses by region overlap: a pose fitter that shares no code with the matcher.

The matcher (``fluorogui.core``: exact mesh silhouette, sub-pixel Canny edges, outline
splines, point-to-curve residuals, Levenberg-Marquardt) fits outlines. This module fits
*regions* instead, so that the two can check each other on real images:

* the image side: the implant is the darkest thing near itself. Around the start pose's
  region, local metal and background levels (normalised Gaussian averages inside it and
  in a ring 2-6 px outside it) turn the image into a soft metal fraction
  ``clip((background - I) / (background - metal), 0, 1)``, kept within 3 px of the edge
  of the region where it exceeds 1/2 (1 inside, 0 outside). Blurring preserves an
  edge's area, so this places a blurred edge where the step was, without an edge
  detector, provided the background is the level the edge steps to: on real trays the
  bone and cement next to the metal make the background rise for 10-20 px outward, and
  a ring further out (6-18 px, as before) put the edge 1-2 px outside the metal. The
  evidence is sampled again around the pose after each stage, and the last stage is run
  again until the evidence was sampled where the fit ends.
* the model side: the triangles of the mesh that face the source are projected here and
  their union (the projected region of the closed mesh) is filled by the winding number
  of their edges on an s x s supersampled grid, smooth along the grid's rows, averaged
  to a coverage fraction per pixel;
* the objective: the squared differences of the two maps, both blurred by the same
  Gaussian (3 px, then 1 px), over the window's pixels inside the field of view and not
  masked out (the other component: ``component_masks``), over all views; minimised over
  the six pose variables (centroid shift, rotation vector about the centroid) by
  ``scipy.optimize.least_squares`` with finite differences of 0.4, then 0.2 mm / deg;
* a fit whose overlap with the evidence is under ``MIN_IOU`` in a view found too little
  of the component there to mean anything: it is refused (``LowOverlap``).

Shared with the matcher: only the conventions (docs/developer/conventions.rst: the pose
``X = R m + t``, ``R = Ry(beta) Rz(gamma) Rx(alpha)``, and the view's numbers: source, plane normal,
in-plane axes, distance, pitch, principal point), duck-typed like
``fluorogui.reference.xray``: rays and projections are computed here. The caller reads
files (calibrations, images, meshes) with ``fluorogui.io``. Only numpy, scipy and OpenCV;
no import from ``fluorogui`` (an import-linter contract keeps it so).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

#: the fit's stages: (blur sigma px, supersampling, finite-difference step in mm and deg,
#: the background's (mode, near, far) px for ``background_level``)
STAGES = ((3.0, 1, 0.4, ("ring", 2.0, 6.0)), (1.0, 3, 0.2, ("ring", 2.0, 6.0)))
#: the last stage is run again on evidence sampled anew while its pose moves by more than
#: this (mm of the centroid or degrees), at most ``SETTLE`` more times
SETTLE_MOVE, SETTLE = 0.05, 2
#: a fit whose overlap (IoU) is under this in a view found too little of the component there
MIN_IOU = 0.5


# -- conventions (docs/developer/conventions.rst), written here ----------------------------
def rotation(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """R = Ry(beta) Rz(gamma) Rx(alpha), degrees (intrinsic Y-Z-X)."""
    return Rotation.from_euler("YZX", [beta, gamma, alpha], degrees=True).as_matrix()


def angles(R: np.ndarray) -> np.ndarray:
    """(alpha, beta, gamma) in degrees back from R."""
    gamma = np.arcsin(np.clip(R[1, 0], -1.0, 1.0))
    alpha = np.arctan2(-R[1, 2], R[1, 1])
    beta = np.arctan2(-R[2, 0], R[0, 0])
    return np.degrees([alpha, beta, gamma])


def project(view, points: np.ndarray) -> np.ndarray:
    """World points (N, 3) to pixels (N, 2): the ray from the source meets the plane."""
    d = np.asarray(points, dtype=float) - np.asarray(view.source, dtype=float)
    scale = view.distance / (d @ np.asarray(view.normal, dtype=float))
    return np.column_stack([view.principal_point[0] + scale * (d @ np.asarray(view.e_u)) / view.pitch[0],
                            view.principal_point[1] + scale * (d @ np.asarray(view.e_v)) / view.pitch[1]])


def pose_difference(a, b) -> np.ndarray:
    """a - b: translation difference (mm) and the angle differences wrapped to +-180 deg."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    d[3:] = (d[3:] + 180.0) % 360.0 - 180.0
    return d


def rotation_angle(a, b) -> float:
    """The angle (deg) of the rotation between poses a and b: free of the Euler angles'
    coupling (near gamma = +-90 deg alpha and beta turn about nearly the same axis)."""
    R = rotation(*np.asarray(a, dtype=float)[3:]) @ rotation(*np.asarray(b, dtype=float)[3:]).T
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


# -- the model's region ----------------------------------------------------------------------
@dataclass
class EdgeMesh:
    """A triangle mesh with its edges listed once: ``edges`` (E, 2) vertex indices and a
    sparse (E, F) matrix ``incidence``: +1 where face f runs along edge e from its first
    to its second vertex, -1 where it runs against it."""

    vertices: np.ndarray
    faces: np.ndarray
    edges: np.ndarray
    incidence: object

    @classmethod
    def from_arrays(cls, vertices, faces) -> "EdgeMesh":
        from scipy.sparse import csr_matrix

        vertices = np.asarray(vertices, dtype=float)
        faces = np.asarray(faces, dtype=np.int64)
        start = faces.reshape(-1)
        end = faces[:, [1, 2, 0]].reshape(-1)
        lo, hi = np.minimum(start, end), np.maximum(start, end)
        edges, index = np.unique(np.column_stack([lo, hi]), axis=0, return_inverse=True)
        direction = np.where(start == lo, 1.0, -1.0)
        face = np.repeat(np.arange(len(faces)), 3)
        incidence = csr_matrix((direction, (index.reshape(-1), face)), shape=(len(edges), len(faces)))
        return cls(vertices, faces, edges, incidence)


def coverage(view, world_vertices: np.ndarray, mesh: EdgeMesh, box, *, s: int) -> np.ndarray:
    """Fraction (H, W) of each pixel of ``box`` = (u0, v0, u1, v1) covered by the projection
    of the closed mesh (placed at ``world_vertices``), from s x s samples per pixel.

    The region is the union of the triangles facing the source; they all project with
    the same orientation, so the number of layers over a sample is the winding number of
    their edges: each directed edge adds +-1 to the samples right of where it crosses a
    sample row (the sample it falls in by the part right of it: smooth along rows), and
    a running sum along the row counts. An edge's net weight is the sum
    over its triangles that face the source of their direction along it, so edges
    inside the region cancel and the work goes with the outline's length."""
    u0, v0, u1, v1 = box
    width, height = (u1 - u0) * s, (v1 - v0) * s
    P = world_vertices[mesh.faces]
    normals = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    towards = np.einsum("ij,ij->i", normals, P[:, 0] - np.asarray(view.source, dtype=float))
    # a closed mesh faces the source with as much as it turns away: either side will do
    weight = mesh.incidence @ (towards < 0).astype(float)
    live = np.nonzero(weight)[0]
    q = (project(view, world_vertices) - (u0, v0) + 0.5) * s - 0.5  # sample-grid coordinates
    a, b = mesh.edges[live, 0], mesh.edges[live, 1]
    down = q[a, 1] < q[b, 1]
    top, bottom = np.where(down, a, b), np.where(down, b, a)
    sign = np.where(down, weight[live], -weight[live])
    r0 = np.maximum(np.ceil(q[top, 1]).astype(np.int64), 0)
    r1 = np.minimum(np.ceil(q[bottom, 1]).astype(np.int64), height)  # rows r0 .. r1 - 1
    counts = np.maximum(r1 - r0, 0)
    keep = np.nonzero(counts)[0]
    winding = np.zeros(height * (width + 1), dtype=np.float32)
    if len(keep):
        owner = np.repeat(keep, counts[keep])
        row = r0[owner] + np.arange(owner.size) - np.repeat(np.cumsum(counts[keep]) - counts[keep], counts[keep])
        ta, tb = q[top[owner]], q[bottom[owner]]
        x = ta[:, 0] + (row - ta[:, 1]) * (tb[:, 0] - ta[:, 0]) / (tb[:, 1] - ta[:, 1])
        # a sample is a unit box along its row: the edge at x covers the part of sample
        # k = round(x) right of x, and every sample after it wholly (continuous in x)
        k = np.floor(x + 0.5)
        part = k + 0.5 - x
        k = k.astype(np.int64)
        w = sign[owner]
        base = row * (width + 1)
        winding = (np.bincount(base + np.clip(k, 0, width), weights=np.where(k < 0, w, w * part),
                               minlength=winding.size)
                   + np.bincount(base + np.clip(k + 1, 0, width), weights=np.where(k < 0, 0.0, w * (1.0 - part)),
                                 minlength=winding.size)).astype(np.float32)
    layers = np.cumsum(winding.reshape(height, width + 1)[:, :width], axis=1)
    return np.minimum(np.abs(layers), 1.0).reshape(v1 - v0, s, u1 - u0, s).mean(axis=(1, 3))


# -- the image's region ----------------------------------------------------------------------
def field_of_view(image: np.ndarray, erode_px: int = 6) -> np.ndarray:
    """The intensifier's round field of view: the convex hull of the largest connected
    not-black region (metal inside it may be as black as the outside), eroded by
    ``erode_px`` (the rim is dark and soft)."""
    lit = (cv2.GaussianBlur(image.astype(np.float32), (0, 0), 3) > 0.04).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(lit)
    if n <= 1:
        return np.ones(image.shape, dtype=bool)
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    contours, _ = cv2.findContours((labels == biggest).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    filled = np.zeros(image.shape, dtype=np.uint8)
    cv2.fillConvexPoly(filled, cv2.convexHull(np.vstack(contours)), 1)
    if erode_px:
        filled = cv2.erode(filled, _disc(erode_px))
    return filled.astype(bool)


def _disc(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def _local_mean(values: np.ndarray, where: np.ndarray, sigma: float, fallback: float) -> np.ndarray:
    """Normalised Gaussian average of ``values`` over the pixels ``where``, everywhere."""
    weight = where.astype(np.float32)
    num = cv2.GaussianBlur(values * weight, (0, 0), sigma)
    den = cv2.GaussianBlur(weight, (0, 0), sigma)
    return np.where(den > 1e-3, num / np.maximum(den, 1e-6), fallback).astype(np.float32)


def metal_fraction(window: np.ndarray, valid: np.ndarray, prior: np.ndarray, *, band: int = 3,
                   margin: int = 6, background: str = "ring", near: float = 2.0, far: float = 6.0,
                   sigma: float = 10.0) -> np.ndarray:
    """Soft metal fraction in [0, 1] of an image window (float, dark = metal).

    ``prior`` (bool, the model's region at the start pose) only tells where to sample the
    levels: the metal's inside it (eroded by ``margin`` px), averaged locally (a normalised
    Gaussian, ``sigma`` px: metal thickness varies across a component), and the
    background's in the ring ``near`` .. ``far`` px outside it (``background_level``).
    The fraction ``f = (background - I) / (background - metal)`` is kept within ``band`` px
    of the edge of the region f > 1/2 (cleaned by an opening; the parts meeting the inner
    prior), 1 inside it and 0 outside: a blurred edge keeps its area, so this places the
    edge without an edge detector."""
    w = window.astype(np.float32)
    prior_u8 = (prior & valid).astype(np.uint8)
    inner = cv2.erode(prior_u8, _disc(margin)).astype(bool) & valid
    if not inner.any():
        return np.zeros_like(w)
    outside = cv2.distanceTransform(1 - prior.astype(np.uint8), cv2.DIST_L2, 5)  # px from the prior, 0 inside
    bg = background_level(w, valid, outside, background, near=near, far=far, sigma=sigma)
    if bg is None:
        return np.zeros_like(w)
    metal = _local_mean(w, inner, sigma, float(np.median(w[inner])))
    f = np.clip((bg - w) / np.maximum(bg - metal, 1e-3), 0.0, 1.0)
    dark = ((f > 0.5) & valid).astype(np.uint8)
    dark = cv2.morphologyEx(cv2.morphologyEx(dark, cv2.MORPH_OPEN, _disc(2)), cv2.MORPH_CLOSE, _disc(1))
    n, labels = cv2.connectedComponents(dark)
    touched = np.unique(labels[(labels > 0) & inner])
    region = np.isin(labels, touched).astype(np.uint8)
    grown = cv2.dilate(region, _disc(band)).astype(bool)
    core = cv2.erode(region, _disc(band)).astype(bool)
    return np.where(core, 1.0, np.where(grown, f, 0.0)).astype(np.float32)


def background_level(w: np.ndarray, valid: np.ndarray, outside: np.ndarray, mode: str, *, near: float,
                     far: float, sigma: float) -> np.ndarray | None:
    """The background's level at every pixel of a window, from the ring of valid pixels
    ``near`` .. ``far`` px outside the prior (``outside``: each pixel's distance from it).

    ``"ring"``: the ring's local mean (a normalised Gaussian, ``sigma`` px). ``"slope"``:
    a local straight line in the distance, fitted over the ring (the same Gaussian
    weights) and read at each pixel's own distance (at 0 inside the prior, at ``far``
    beyond the ring): the level the background has at the edge, where bone and cement next
    to the implant make it rise outward. Where the ring is too thin to give a slope, its
    mean. None when the ring is empty. The fit reads a ring 2-6 px out: against the truth
    on X-ray model images with the real trays' slope, a slope fitted 3-10 px out turned
    the tray 2-4 times as far off about its mediolateral axis (the real slope is flat for
    a few pixels, then steep), the ring 6-18 px out 10 times."""
    ring = valid & (outside >= near) & (outside <= far)
    if not ring.any():
        return None
    fallback = float(np.median(w[ring]))
    mean = _local_mean(w, ring, sigma, fallback)
    if mode == "ring":
        return mean
    weight = ring.astype(np.float32)
    d = np.where(ring, outside, 0.0).astype(np.float32)
    g = lambda a: cv2.GaussianBlur(a, (0, 0), sigma)  # noqa: E731
    s0, s1, s2 = g(weight), g(weight * d), g(weight * d * d)
    si, sdi = g(weight * w), g(weight * d * w)
    det = s0 * s2 - s1 * s1
    # the spread of the ring's distances under the window: a slope needs some
    ok = (s0 > 1e-3) & (det > 0.25 * (far - near) ** 2 / 12.0 * s0 * s0)
    slope = np.where(ok, (s0 * sdi - s1 * si) / np.where(ok, det, 1.0), 0.0)
    at = np.clip(outside, 0.0, far)
    level = np.where(s0 > 1e-3, (si - slope * s1) / np.maximum(s0, 1e-6) + slope * at, fallback)
    return np.where(ok, level, mean).astype(np.float32)


# -- the fit -----------------------------------------------------------------------------------
@dataclass
class ViewData:
    """One view's evidence: the window (u0, v0, u1, v1), its metal fraction and the pixels
    that count (inside the field of view, not masked out)."""

    view: object
    box: tuple[int, int, int, int]
    target: np.ndarray
    valid: np.ndarray


@dataclass
class RegionFit:
    """A fitted pose (mm, deg), the overlap (IoU of the model's region and the metal,
    both at half coverage, valid pixels of the window) per view, the final objective
    (mean squared difference of the blurred maps) and the work done."""

    pose: np.ndarray
    iou: list[float]
    objective: float
    evaluations: int
    seconds: float
    success: bool
    message: str = ""
    stages: list = field(default_factory=list)
    evidence: list = field(default_factory=list, repr=False)  # the final stage's ViewData

    def iou_at(self, mesh: "EdgeMesh", pose, s: int = STAGES[-1][1]) -> list[float]:
        """The overlap per view of another pose's region with this fit's evidence."""
        pose = np.asarray(pose, dtype=float)
        world = mesh.vertices @ rotation(*pose[3:]).T + pose[:3]
        return [iou(d, coverage(d.view, world, mesh, d.box, s=s)) for d in self.evidence]


class LowOverlap(RuntimeError):
    """A region fit refused: in some view its overlap with the evidence is under the
    minimum (its window held too little of the component, so the pose means nothing).
    ``fit`` is the refused fit, for counting it apart."""

    def __init__(self, fit: RegionFit, min_iou: float):
        self.fit = fit
        worst = int(np.argmin(fit.iou))
        super().__init__(f"region fit refused: its overlap in view {worst + 1} is {fit.iou[worst]:.2f}, under "
                         f"{min_iou:g}; its window holds too little of the component")


def component_masks(views, mesh: EdgeMesh, pose, dilate_px: int = 3) -> list[np.ndarray]:
    """Per view, the image pixels of a component's projected region at ``pose`` (mm, deg),
    dilated by ``dilate_px``: the other component's ``exclude`` for ``fit_pose``."""
    pose = np.asarray(pose, dtype=float)
    world = mesh.vertices @ rotation(*pose[3:]).T + pose[:3]
    out = []
    for view in views:
        w, h = view.image_size
        box = window_box(view, world, dilate_px + 1)
        region = np.zeros((h, w), dtype=np.uint8)
        u0, v0, u1, v1 = box
        region[v0:v1, u0:u1] = coverage(view, world, mesh, box, s=1) > 1e-3  # not the sums' float residue
        out.append(cv2.dilate(region, _disc(dilate_px)).astype(bool) if dilate_px else region.astype(bool))
    return out


def window_box(view, world_vertices: np.ndarray, pad: int) -> tuple[int, int, int, int]:
    """The pixel box around the projected vertices, ``pad`` pixels wider, clipped to the image."""
    uv = project(view, world_vertices)
    w, h = view.image_size
    u0 = int(np.clip(np.floor(uv[:, 0].min()) - pad, 0, w))
    v0 = int(np.clip(np.floor(uv[:, 1].min()) - pad, 0, h))
    u1 = int(np.clip(np.ceil(uv[:, 0].max()) + pad + 1, 0, w))
    v1 = int(np.clip(np.ceil(uv[:, 1].max()) + pad + 1, 0, h))
    return u0, v0, max(u0 + 1, u1), max(v0 + 1, v1)


def prepare_views(views, images, world_vertices: np.ndarray, mesh: EdgeMesh, *, pad: int = 30,
                  exclude=None, fields=None, background=STAGES[-1][3]) -> list[ViewData]:
    """The evidence of each view around the model placed at a start pose (world vertices).
    ``exclude``: per view a boolean image mask (or None) of pixels to ignore; ``fields``:
    per view the field-of-view mask (``field_of_view`` finds an
    intensifier's round one; default: the whole image)."""
    out = []
    for k, (view, image) in enumerate(zip(views, images)):
        box = window_box(view, world_vertices, pad)
        u0, v0, u1, v1 = box
        valid = (fields[k][v0:v1, u0:u1].copy() if fields is not None and fields[k] is not None
                 else np.ones((v1 - v0, u1 - u0), dtype=bool))
        if exclude is not None and exclude[k] is not None:
            valid &= ~exclude[k][v0:v1, u0:u1]
        prior = coverage(view, world_vertices, mesh, box, s=1) >= 0.5
        mode, near, far = background
        out.append(ViewData(view, box, metal_fraction(image[v0:v1, u0:u1], valid, prior, background=mode,
                                                      near=near, far=far), valid))
    return out


def _blur(a: np.ndarray, sigma: float) -> np.ndarray:
    return cv2.GaussianBlur(a.astype(np.float32), (0, 0), sigma) if sigma > 0 else a.astype(np.float32)


def _place(vertices, centroid, R0, c0, *, p):
    """World vertices for parameters p = (centroid shift mm, rotation vector deg) about the start."""
    R = Rotation.from_rotvec(np.radians(p[3:])).as_matrix() @ R0
    return (vertices - centroid) @ R.T + c0 + p[:3], R


def iou(data: ViewData, cover: np.ndarray) -> float:
    a = (cover >= 0.5) & data.valid
    b = (data.target >= 0.5) & data.valid
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 0.0


def overlap_at(views, images, mesh: EdgeMesh, pose, *, exclude=None, fields=None, pad: int = 20,
               s: int = STAGES[-1][1]) -> list[float]:
    """Per view, the overlap (IoU) of the region at ``pose`` with the dark region sampled
    around it, without fitting: how well a given pose (another method's) explains the
    images where a fit from it is refused."""
    pose = np.asarray(pose, dtype=float)
    world = mesh.vertices @ rotation(*pose[3:]).T + pose[:3]
    data = prepare_views(views, images, world, mesh, pad=pad, exclude=exclude, fields=fields)
    return [iou(d, coverage(d.view, world, mesh, d.box, s=s)) for d in data]


def fit_pose(views, images, mesh: EdgeMesh, start, *, exclude=None, fields=None, pad: int = 20,
             stages=STAGES, max_nfev: int = 30, settle: int = SETTLE, min_iou: float | None = MIN_IOU) -> RegionFit:
    """Fit the pose of one component (``EdgeMesh`` in its own coordinates) to the dark
    regions of one or more views, from ``start`` (x, y, z, alpha, beta, gamma: mm, deg).

    ``exclude``: per view a boolean image mask (or None) of pixels to leave out, such as
    the other component's region (``component_masks``). Raises ``LowOverlap`` when the
    fit's overlap is under ``min_iou`` in a view (None: never)."""
    t0 = time.perf_counter()
    vertices = mesh.vertices
    start = np.asarray(start, dtype=float)
    centroid = vertices.mean(0)
    R0 = rotation(*start[3:])
    c0 = R0 @ centroid + start[:3]
    p = np.zeros(6)
    evaluations, success, message, history, moved = 0, True, "", [], np.zeros(6)

    plan = list(stages) + [stages[-1]] * settle
    for k, (sigma, s, step, background) in enumerate(plan):
        if k >= len(stages) and np.max(np.abs(moved)) <= SETTLE_MOVE:
            break  # the evidence was sampled where the fit ended: settled
        # the evidence is sampled around the pose reached so far (levels, window)
        data = prepare_views(views, images, _place(vertices, centroid, R0, c0, p=p)[0], mesh, pad=pad,
                             exclude=exclude, fields=fields,
                             background=background)
        targets = [_blur(d.target, sigma)[d.valid] for d in data]

        def residuals(q, *, s=s, sigma=sigma, data=data, targets=targets):  # this stage's evidence
            world, _ = _place(vertices, centroid, R0, c0, p=q)
            return np.concatenate([_blur(coverage(d.view, world, mesh, d.box, s=s), sigma)[d.valid] - t
                                   for d, t in zip(data, targets)])

        # the parameters start at 0 and stay within a few units: diff_step (relative to
        # max(1, |x|)) is then an absolute step in mm and degrees
        sol = least_squares(residuals, p, method="trf", diff_step=step, jac="2-point",
                            max_nfev=max_nfev, xtol=1e-5, ftol=1e-8)
        evaluations += sol.nfev + 6 * (sol.njev or 0)
        moved = sol.x - p
        p = sol.x
        history.append((sigma, s, float(np.mean(sol.fun ** 2)), int(sol.nfev)))
        success, message = success and sol.status > 0, sol.message

    world, R = _place(vertices, centroid, R0, c0, p=p)
    t = (c0 + p[:3]) - R @ centroid
    covers = [coverage(d.view, world, mesh, d.box, s=stages[-1][1]) for d in data]
    fit = RegionFit(np.r_[t, angles(R)], [iou(d, c) for d, c in zip(data, covers)], history[-1][2],
                    evaluations, time.perf_counter() - t0, success, message, history, data)
    if min_iou is not None and min(fit.iou) < min_iou:
        raise LowOverlap(fit, min_iou)
    return fit
