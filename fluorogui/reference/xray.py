"""An X-ray image model for validation that shares no code with the matcher.

The matcher fits the silhouette of a mesh (``core.projection.silhouette``) and the old validation
images were drawn with the same idea (``simulation.render``: a filled silhouette), so a bias of
that model would cancel out. This module images the physics instead:

* every detector sample (``supersample`` x ``supersample`` per pixel) gets the length
  of its ray inside each closed mesh, exactly: the signed sum over the triangles it
  crosses of the distance from the source (+ where the ray leaves, - where it enters);
* Beer-Lambert attenuation, ``exp(-sum mu L)``, metal strongly, plus a soft-tissue and a
  bone background (infinite cylinders, closed-form chords) that the implant overlaps;
* optional bone and cement about an implant (``fluorogui.reference.zone.Zone``): an
  attenuation that falls off with the distance from the implant's surface, on the bone's
  side, so that the metal's edge stands on a sloped background as on real images;
* blur of the focal spot (its size times the geometric unsharpness ``(m - 1)``) and of
  the detector, quantum noise (Poisson counts of ``photons`` per pixel of air), optional
  radial (image-intensifier) distortion, and 8- or 16-bit output.

Any geometry: the view is read from its source, plane normal, in-plane axes, source to
plane distance, pixel pitch and principal point (the attributes of
``fluorogui.core.projection.geometry.View``, which is not imported: rays are built here from those
numbers). Only numpy, scipy and OpenCV; no import from ``fluorogui`` at all (an
import-linter contract keeps it so).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

#: linear attenuation coefficients (1/mm) at a fluoroscopic beam's effective energy of
#: about 60 keV (mass attenuation times density; NIST XCOM values: iron 1.2 cm2/g, so
#: CoCr at 8.3 g/cm3 ~1.0/mm, titanium alloy ~0.5/mm; cortical bone ~0.06/mm, water 0.02/mm)
MU_METAL = 1.0
MU_TITANIUM = 0.5
MU_BONE = 0.06
MU_TISSUE = 0.02


@dataclass
class Body:
    """A closed triangle mesh in world millimetres and its attenuation (1/mm)."""

    vertices: np.ndarray
    faces: np.ndarray
    mu: float = MU_METAL


@dataclass
class Cylinder:
    """An infinite cylinder (soft tissue, a bone shaft): a point on its axis, its axis
    direction, radius (mm) and attenuation (1/mm)."""

    point: tuple[float, float, float]
    axis: tuple[float, float, float]
    radius: float
    mu: float


@dataclass
class XrayModel:
    """How images are made; the defaults give a knee-like, fairly clean image."""

    supersample: int = 3
    focal_spot_mm: float = 0.6  # focal spot size (FWHM)
    detector_blur_px: float = 0.7  # Gaussian sigma of the detector / intensifier blur
    photons: float | None = 3000.0  # mean counts per pixel without an object (None: no noise)
    background: list[Cylinder] = field(default_factory=lambda: [
        Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 50.0, MU_TISSUE),  # the leg
        Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 14.0, MU_BONE),  # a bone shaft along it
    ])
    zones: list = field(default_factory=list)  # fluorogui.reference.zone.Zone: bone and cement about an implant
    distortion_k1: float = 0.0  # radial distortion: r_observed = r (1 + k1 r^2), r in units of half the width
    bits: int = 16

    def __post_init__(self):
        if self.bits not in (8, 16):
            raise ValueError("bits must be 8 or 16")
        if self.supersample < 1:
            raise ValueError("supersample must be at least 1")


# -- rays ------------------------------------------------------------------------------------
def _sample_grid(view, box, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Sub-pixel sample centres (u, v) in pixels over the pixel box (u0, v0, u1, v1), end
    exclusive: s x s per pixel, at (i + 0.5) / s - 0.5."""
    u0, v0, u1, v1 = box
    us = (np.arange((u1 - u0) * s) + 0.5) / s - 0.5 + u0
    vs = (np.arange((v1 - v0) * s) + 0.5) / s - 0.5 + v0
    return np.meshgrid(us, vs)


def _directions(view, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unnormalised ray directions from the source through detector pixels (u, v):
    the plane point at ``distance`` along the normal plus the in-plane offsets."""
    du = (u - view.principal_point[0]) * view.pitch[0]
    dv = (v - view.principal_point[1]) * view.pitch[1]
    return (view.distance * np.asarray(view.normal)[None, :] + du.reshape(-1, 1) * np.asarray(view.e_u)[None, :]
            + dv.reshape(-1, 1) * np.asarray(view.e_v)[None, :])


def _to_detector(view, points: np.ndarray) -> np.ndarray:
    """Pixel coordinates (K, 2) where rays from the source through world points meet the detector."""
    d = np.asarray(points, dtype=float) - np.asarray(view.source)
    w = d @ np.asarray(view.normal)
    scale = view.distance / w
    return np.column_stack([view.principal_point[0] + scale * (d @ np.asarray(view.e_u)) / view.pitch[0],
                            view.principal_point[1] + scale * (d @ np.asarray(view.e_v)) / view.pitch[1]])


def path_length(view, body: Body, s: int, box) -> np.ndarray:
    """Length (mm) of each sample ray inside ``body`` over the pixel box, shape (H s, W s).

    For a closed, consistently oriented mesh the length is the sum over the triangles a
    ray crosses of its distance to the crossing, counted + where the ray leaves (the
    face turns away from the source) and - where it enters; the sign of the total fixes
    the mesh's orientation. Rays through a hole of an open mesh (entries and exits do
    not pair up, or exactly through an edge two triangles share) are inpainted from
    their neighbours."""
    u0, v0, u1, v1 = box
    width, height = (u1 - u0) * s, (v1 - v0) * s
    total = np.zeros(width * height)
    net = np.zeros(width * height)
    V = np.asarray(body.vertices, dtype=float)
    F = np.asarray(body.faces, dtype=np.int64)
    src = np.asarray(view.source, dtype=float)
    normal, e_u, e_v = (np.asarray(a, dtype=float) for a in (view.normal, view.e_u, view.e_v))
    if np.any((V - src) @ normal <= 0):
        raise ValueError("part of the mesh lies behind the source")
    P = V[F]  # (T, 3, 3)
    n_tri = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    # a ray's direction d = D n + du e_u + dv e_v is linear in the sample position, so its
    # dot product with a triangle's normal is too: n.d = c0 + cu x + cv y (x, y: sample grid)
    cx, cy = view.principal_point
    pu, pv = view.pitch
    ax, bx = pu / s, ((u0 - 0.5) + 0.5 / s - cx) * pu  # du = ax * x + bx
    ay, by = pv / s, ((v0 - 0.5) + 0.5 / s - cy) * pv
    nn, nu, nv = n_tri @ normal, n_tri @ e_u, n_tri @ e_v
    c0 = view.distance * nn + bx * nu + by * nv
    cu, cv = ax * nu, ay * nv
    numer = np.einsum("ij,ij->i", n_tri, P[:, 0] - src)
    # sample-grid coordinates of the projected corners: x = (u - u0 + 0.5) s - 0.5
    q = (_to_detector(view, V)[F] - (u0, v0) + 0.5) * s - 0.5  # (T, 3, 2)
    lo = np.maximum(np.ceil(q.min(1)).astype(np.int64), 0)
    hi = np.minimum(np.floor(q.max(1)).astype(np.int64), [width - 1, height - 1])
    nx, ny = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0), np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    counts = nx * ny
    a, b, c = q[:, 0], q[:, 1], q[:, 2]
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    keep = np.nonzero((counts > 0) & (np.abs(area) > 1e-9))[0]
    start, chunk = 0, 3_000_000
    while start < len(keep):
        cum = np.cumsum(counts[keep[start:]])
        stop = start + max(1, int(np.searchsorted(cum, chunk)))
        tri = keep[start:stop]
        start = stop
        owner = np.repeat(tri, counts[tri])
        k = np.arange(owner.size) - np.repeat(np.cumsum(counts[tri]) - counts[tri], counts[tri])
        x = lo[owner, 0] + k % nx[owner]
        y = lo[owner, 1] + k // nx[owner]
        px, py = x.astype(float), y.astype(float)
        sgn = np.sign(area[owner])
        inside = np.ones(owner.size, dtype=bool)
        for A, B in ((a, b), (b, c), (c, a)):
            A, B = A[owner], B[owner]
            inside &= ((B[:, 0] - A[:, 0]) * (py - A[:, 1]) - (B[:, 1] - A[:, 1]) * (px - A[:, 0])) * sgn >= 0
        owner, x, y, px, py = owner[inside], x[inside], y[inside], px[inside], py[inside]
        dot = c0[owner] + cu[owner] * px + cv[owner] * py  # n.d
        du, dv = ax * px + bx, ay * py + by
        length = np.sqrt(view.distance ** 2 + du * du + dv * dv)  # |d|
        ok = np.abs(dot) > 1e-12 * np.abs(numer[owner]).clip(1e-300)
        dist = numer[owner[ok]] / dot[ok] * length[ok]  # distance from the source, along the ray
        sign = np.sign(dot[ok])  # + leaving (normal along the ray), - entering
        idx = y[ok] * width + x[ok]
        total += np.bincount(idx, weights=dist * sign, minlength=total.size)
        net += np.bincount(idx, weights=sign, minlength=total.size)
    total, net = total.reshape(height, width), net.reshape(height, width)
    bad = net != 0
    if total[~bad].sum() < 0:  # the mesh's normals point inwards
        total = -total
    if bad.any():  # rays through holes or exactly through shared edges: filled from around
        total = _fill_from_neighbours(total, bad)
    return total


def _fill_from_neighbours(values: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """``values`` with the ``bad`` samples replaced by the Gaussian-weighted mean of the
    good ones near them (normalised convolution, widening until every gap is reached)."""
    out = values.copy()
    todo = bad.copy()
    good = (~bad).astype(float)
    known = np.where(bad, 0.0, values)
    sigma = 0.7
    while todo.any() and sigma < 4 * max(values.shape):
        weight = cv2.GaussianBlur(good, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
        mean = cv2.GaussianBlur(known, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
        reach = todo & (weight > 0.05)
        out[reach] = mean[reach] / weight[reach]
        todo &= ~reach
        sigma *= 2.0
    return out


def cylinder_chord(view, cylinder: Cylinder, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Length (mm) of the rays through pixels (u, v) inside an infinite cylinder."""
    d = _directions(view, u, v)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    axis = np.asarray(cylinder.axis, dtype=float)
    axis /= np.linalg.norm(axis)
    w = np.asarray(view.source, dtype=float) - np.asarray(cylinder.point, dtype=float)
    dp = d - np.outer(d @ axis, axis)  # components perpendicular to the axis
    wp = w - (w @ axis) * axis
    A = np.einsum("ij,ij->i", dp, dp)
    B = 2.0 * dp @ wp
    C = wp @ wp - cylinder.radius ** 2
    disc = B * B - 4 * A * C
    chord = np.where((disc > 0) & (A > 1e-15), np.sqrt(np.maximum(disc, 0.0)) / np.maximum(A, 1e-15), 0.0)
    return chord.reshape(np.shape(u))


# -- the image ---------------------------------------------------------------------------------
def _box_of(view, bodies, pad: int) -> tuple[int, int, int, int]:
    w, h = view.image_size
    pts = np.vstack([_to_detector(view, b.vertices) for b in bodies]) if bodies else np.zeros((0, 2))
    if len(pts) == 0:
        return 0, 0, 0, 0
    u0 = int(np.clip(np.floor(pts[:, 0].min()) - pad, 0, w))
    v0 = int(np.clip(np.floor(pts[:, 1].min()) - pad, 0, h))
    u1 = int(np.clip(np.ceil(pts[:, 0].max()) + pad + 1, 0, w))
    v1 = int(np.clip(np.ceil(pts[:, 1].max()) + pad + 1, 0, h))
    return u0, v0, max(u0, u1), max(v0, v1)


def line_integrals(view, bodies: list[Body], model: XrayModel) -> np.ndarray:
    """sum(mu L) per pixel sample over the whole image at pixel resolution outside the
    bodies' box and ``supersample`` resolution inside it; returned as the transmitted
    fraction exp(-sum mu L) per pixel, box-averaged (H, W) after the blur."""
    w, h = view.image_size
    s = model.supersample
    # background at pixel resolution (smooth), evaluated at pixel centres
    uu, vv = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    mu_l = np.zeros((h, w))
    for cyl in model.background:
        mu_l += cyl.mu * cylinder_chord(view, cyl, uu, vv)
    # zones are smooth: integrated at pixel centres, interpolated to the sub-pixel samples
    zones = sum((zone.integral(view, uu, vv) for zone in model.zones), np.zeros((h, w)))
    mu_l += zones
    transmitted = np.exp(-mu_l)
    box = _box_of(view, bodies, pad=8)
    u0, v0, u1, v1 = box
    if u1 > u0 and v1 > v0:
        su, sv = _sample_grid(view, box, s)
        fine = np.zeros(su.shape)
        for cyl in model.background:
            fine += cyl.mu * cylinder_chord(view, cyl, su, sv)
        if model.zones:  # linear between pixel centres: sample (i + 0.5) / s - 0.5 of the pixel grid
            fine += cv2.resize(zones[v0:v1, u0:u1], (su.shape[1], su.shape[0]), interpolation=cv2.INTER_LINEAR)
        for body in bodies:
            fine += body.mu * path_length(view, body, s, box)
        fine_t = np.exp(-fine)
        sigma = _blur_sigma(view, bodies, model) * s
        if sigma > 0:
            fine_t = cv2.GaussianBlur(fine_t, (0, 0), sigma)
        coarse = fine_t.reshape(v1 - v0, s, u1 - u0, s).mean(axis=(1, 3))
        outside = transmitted.copy()
        transmitted[v0:v1, u0:u1] = coarse
        # the background outside the box gets the same blur (it is smooth: a small effect)
        pix_sigma = _blur_sigma(view, bodies, model)
        if pix_sigma > 0:
            outside = cv2.GaussianBlur(outside, (0, 0), pix_sigma)
        mask = np.ones((h, w), dtype=bool)
        mask[v0:v1, u0:u1] = False
        transmitted[mask] = outside[mask]
    return transmitted


def _blur_sigma(view, bodies, model: XrayModel) -> float:
    """Total Gaussian blur sigma (px): the detector's and the focal spot's penumbra."""
    focal = 0.0
    if bodies and model.focal_spot_mm > 0:
        centre = np.vstack([b.vertices for b in bodies]).mean(0)
        depth = float((centre - np.asarray(view.source)) @ np.asarray(view.normal))
        magnification = view.distance / depth
        focal = model.focal_spot_mm * (magnification - 1.0) / float(np.mean(view.pitch)) / 2.355
    return float(np.hypot(focal, model.detector_blur_px))


def distort(image: np.ndarray, k1: float) -> np.ndarray:
    """Radial distortion about the image centre: the observed pixel at radius r shows the
    ideal image at r (1 + k1 r^2) ... inverted, so that the ideal point at radius r_i is
    seen at r_o = r_i (1 + k1 r_i^2); r in units of half the image width."""
    if k1 == 0:
        return image
    h, w = image.shape
    cx, cy, half = (w - 1) / 2.0, (h - 1) / 2.0, w / 2.0
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    ro = np.hypot(uu - cx, vv - cy) / half
    ri = _invert_radial(ro, k1)
    scale = np.divide(ri, ro, out=np.ones_like(ro), where=ro > 0)
    map_u = (cx + (uu - cx) * scale).astype(np.float32)
    map_v = (cy + (vv - cy) * scale).astype(np.float32)
    return cv2.remap(image.astype(np.float32), map_u, map_v, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)


def undistort_points(uv: np.ndarray, k1: float, image_size) -> np.ndarray:
    """Ideal pixel positions of observed (distorted) points under ``distort``'s model."""
    w, h = image_size
    cx, cy, half = (w - 1) / 2.0, (h - 1) / 2.0, w / 2.0
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    ro = np.hypot(uv[:, 0] - cx, uv[:, 1] - cy) / half
    ri = _invert_radial(ro, k1)
    scale = np.divide(ri, ro, out=np.ones_like(ro), where=ro > 0)
    return np.column_stack([cx + (uv[:, 0] - cx) * scale, cy + (uv[:, 1] - cy) * scale])


def undistort_image(image: np.ndarray, k1: float) -> np.ndarray:
    """The ideal image back from a distorted one (the correction a user applies)."""
    if k1 == 0:
        return image
    h, w = image.shape
    cx, cy, half = (w - 1) / 2.0, (h - 1) / 2.0, w / 2.0
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    ri = np.hypot(uu - cx, vv - cy) / half
    scale = 1.0 + k1 * ri ** 2  # where the ideal radius ri is observed
    map_u = (cx + (uu - cx) * scale).astype(np.float32)
    map_v = (cy + (vv - cy) * scale).astype(np.float32)
    return cv2.remap(image.astype(np.float32), map_u, map_v, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)


def _invert_radial(ro: np.ndarray, k1: float) -> np.ndarray:
    """r_i with r_i (1 + k1 r_i^2) = r_o (Newton from r_o)."""
    ri = np.array(ro, dtype=float)
    for _ in range(20):
        ri -= (ri * (1 + k1 * ri ** 2) - ro) / (1 + 3 * k1 * ri ** 2)
    return ri


def xray_image(view, bodies: list[Body], model: XrayModel | None = None,
               rng: np.random.Generator | None = None) -> np.ndarray:
    """The detector image (H, W) in [0, 1], quantised to ``model.bits``: bright where
    little is in the way, dark behind metal."""
    model = model or XrayModel()
    return detector_image(line_integrals(view, bodies, model), model, rng)


def detector_image(transmitted: np.ndarray, model: XrayModel, rng: np.random.Generator | None = None) -> np.ndarray:
    """``xray_image`` from the noise-free transmitted fraction (``line_integrals``): quantum
    noise, distortion, gain and quantisation. Several noise draws of one scene share the
    costly ``line_integrals``."""
    rng = rng or np.random.default_rng(0)
    if model.photons:
        transmitted = rng.poisson(transmitted * model.photons) / float(model.photons)
    if model.distortion_k1:
        transmitted = distort(transmitted, model.distortion_k1)
    # automatic gain: the brightest pixel (air, where there is some) at 95 % of full scale
    transmitted = transmitted * (0.95 / max(float(transmitted.max()), 1e-12))
    levels = 255.0 if model.bits == 8 else 65535.0
    image = np.round(np.clip(transmitted, 0.0, 1.0) * levels) / levels
    return image.astype(np.float32)
