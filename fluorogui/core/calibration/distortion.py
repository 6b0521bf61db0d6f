"""Image-intensifier distortion: calibration from a perforated plate, and its correction.

The paper corrects first, then matches. From an image of a plate with a regular grid of
holes (square or hexagonal, known spacing):

1. ``detect_holes``: bright (or dark) blobs of one size, sub-pixel centres from their
   background-subtracted intensity centroid; blobs of another size or shape, and blobs cut
   by the image border, are discarded.
2. ``index_grid``: lattice indices (i, j) grown outwards from the hole nearest the image
   centre, each step predicted from the neighbours already found (so the bending grid is
   followed); holes that fit no lattice site are discarded.
3. ``fit_plate``: the ideal grid and the correction fitted together by linear least
   squares: ``ideal = origin + i a + j b`` (``b`` is ``a`` turned by 90 or 60 degrees) and
   ``ideal = d + nonlinear polynomial terms of d`` about the image centre (degree 2 to
   ``degree``; Gronenschild's global polynomial). The correction thus keeps the image
   scale and orientation at the centre; only the distortion is removed.
4. Optionally a local weighted-mean model (``LocalCorrection``, as XMALab does): a
   second-order fit over the ``neighbours`` nearest holes around each hole, blended with
   weights ``1 - 3 r^2 + 2 r^3`` that reach zero at the farthest of those neighbours;
   outside the plate it falls back to the global polynomial. It nearly interpolates its
   holes, so its residual is also reported with each hole left out (``left_out_px``).

Every model maps distorted pixels to ideal ones (``correct_points``) and back
(``distort_points``, by fixed-point iteration: the distortion is a small departure from
the identity), and corrects or distorts whole images through a remap whose map is
evaluated on a coarse grid (every ``MAP_STEP`` px) and interpolated. OpenCV's lens model
(MayaCam 2.0's ``undistortion`` block) is one more model (``OpenCVCorrection``).
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.spatial import cKDTree

#: Spacing (px) of the grid on which image remap maps are evaluated before interpolation.
MAP_STEP = 4
GRID_ANGLES = {"square": 90.0, "hex": 60.0}
MIN_HOLES = 25


class DistortionError(ValueError):
    """A plate image in which no usable grid of holes was found, or a bad correction."""


# -- models -------------------------------------------------------------------------------------
def _monomials(x: np.ndarray, degree: int, lowest: int = 0) -> np.ndarray:
    """Columns x^p y^q for lowest <= p + q <= degree, in a fixed order."""
    cols = [x[:, 0] ** (n - q) * x[:, 1] ** q for n in range(lowest, degree + 1) for q in range(n + 1)]
    return np.column_stack(cols)


class Correction:
    """A distortion correction: distorted pixels <-> ideal pixels, and images both ways."""

    def correct_points(self, uv) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def distort_points(self, uv, iterations: int = 30) -> np.ndarray:
        """Ideal pixels to distorted ones: the inverse of ``correct_points`` by iteration."""
        target = np.atleast_2d(np.asarray(uv, dtype=float))
        x = target.copy()
        for _ in range(iterations):
            step = self.correct_points(x) - target
            x -= step
            if np.nanmax(np.abs(step), initial=0.0) < 1e-9:
                break
        return x

    def correct_image(self, image: np.ndarray) -> np.ndarray:
        """The image as an ideal (undistorted) intensifier would have recorded it."""
        return _remap(image, self.distort_points)

    def distort_image(self, image: np.ndarray) -> np.ndarray:
        """An ideal image as the distorting intensifier records it."""
        return _remap(image, self.correct_points)

    def to_dict(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError


def _remap(image: np.ndarray, source_of) -> np.ndarray:
    """out(p) = image(source_of(p)), the map evaluated every MAP_STEP px and interpolated."""
    h, w = image.shape[:2]
    us = np.arange(0, w - 1 + MAP_STEP, MAP_STEP, dtype=float)
    vs = np.arange(0, h - 1 + MAP_STEP, MAP_STEP, dtype=float)
    grid = np.stack(np.meshgrid(us, vs), axis=-1).reshape(-1, 2)
    src = source_of(grid).reshape(len(vs), len(us), 2).astype(np.float32)
    # coarse-to-fine: a sample every MAP_STEP px becomes a dense map by bilinear interpolation
    cols = (np.arange(w, dtype=np.float32) / MAP_STEP)[None, :].repeat(h, 0)
    rows = (np.arange(h, dtype=np.float32) / MAP_STEP)[:, None].repeat(w, 1)
    map_u = cv2.remap(np.ascontiguousarray(src[..., 0]), cols, rows, cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_REPLICATE)
    map_v = cv2.remap(np.ascontiguousarray(src[..., 1]), cols, rows, cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_REPLICATE)
    out = cv2.remap(np.asarray(image, dtype=np.float32), map_u, map_v, cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    return out.astype(image.dtype if np.issubdtype(image.dtype, np.floating) else np.float32)


@dataclass
class PolynomialCorrection(Correction):
    """Gronenschild's global polynomial: ideal = d + scale * sum c_pq x^p y^q (p+q >= 2),
    with x = (d - centre) / scale."""

    centre: tuple[float, float]
    scale: float
    degree: int
    coef_u: np.ndarray
    coef_v: np.ndarray

    def correct_points(self, uv) -> np.ndarray:
        d = np.atleast_2d(np.asarray(uv, dtype=float))
        basis = _monomials((d - np.asarray(self.centre)) / self.scale, self.degree, 2)
        return d + self.scale * np.column_stack([basis @ self.coef_u, basis @ self.coef_v])

    def to_dict(self) -> dict:
        return {"model": "polynomial", "centre_px": list(self.centre), "scale_px": self.scale,
                "degree": self.degree, "coef_u": self.coef_u.tolist(), "coef_v": self.coef_v.tolist()}


@dataclass
class LocalCorrection(Correction):
    """Local weighted mean of second-order fits around each hole (XMALab-like)."""

    distorted: np.ndarray  # (N, 2) hole centres in the image
    ideal: np.ndarray  # (N, 2) their ideal positions
    neighbours: int
    fallback: PolynomialCorrection
    _fits: np.ndarray = field(init=False, repr=False)
    _radius: np.ndarray = field(init=False, repr=False)
    _tree: cKDTree = field(init=False, repr=False)
    _members: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        self.distorted = np.asarray(self.distorted, dtype=float)
        self.ideal = np.asarray(self.ideal, dtype=float)
        n = min(self.neighbours, len(self.distorted))
        self._tree = cKDTree(self.distorted)
        dist, idx = self._tree.query(self.distorted, k=n)
        self._radius = dist[:, -1] * 1.0001
        fits = np.empty((len(self.distorted), 2, 6))
        for i in range(len(self.distorted)):
            local = self.distorted[idx[i]] - self.distorted[i]
            basis = _monomials(local / self._radius[i], 2)
            target = self.ideal[idx[i]] - self.distorted[idx[i]]
            fits[i] = np.linalg.lstsq(basis, target, rcond=None)[0].T
        self._fits = fits
        self._members = idx

    def left_out_residuals(self) -> np.ndarray:
        """Residual (px) at each hole predicted without it: every local fit that used the hole
        is refitted without it, and the hole's own fit is left out of the blend. The local
        model nearly interpolates its holes, so only this residual says how well it predicts."""
        out = np.empty(len(self.distorted))
        for i in range(len(self.distorted)):
            d = self.distorted[i]
            near = np.asarray(self._tree.query_ball_point(d, float(self._radius.max())))
            near = near[near != i]
            r = np.linalg.norm(d - self.distorted[near], axis=1) / self._radius[near]
            near, r = near[r < 1.0], r[r < 1.0]
            if len(near) == 0:
                out[i] = np.linalg.norm(self.fallback.correct_points(d[None])[0] - self.ideal[i])
                continue
            w = 1.0 - 3.0 * r**2 + 2.0 * r**3
            values = np.empty((len(near), 2))
            for k, j in enumerate(near):
                members = self._members[j]
                if i in members:
                    members = members[members != i]
                    local = (self.distorted[members] - self.distorted[j]) / self._radius[j]
                    fit = np.linalg.lstsq(_monomials(local, 2), self.ideal[members] - self.distorted[members],
                                          rcond=None)[0].T
                else:
                    fit = self._fits[j]
                values[k] = fit @ _monomials(((d - self.distorted[j]) / self._radius[j])[None], 2)[0]
            out[i] = np.linalg.norm(d + w @ values / w.sum() - self.ideal[i])
        return out

    def correct_points(self, uv) -> np.ndarray:
        d = np.atleast_2d(np.asarray(uv, dtype=float))
        total = np.zeros((len(d), 2))
        weight = np.zeros(len(d))
        reach = float(self._radius.max())
        for i, near in enumerate(self._tree.query_ball_point(d, reach)):
            if not near:
                continue
            near = np.asarray(near)
            r = np.linalg.norm(d[i] - self.distorted[near], axis=1) / self._radius[near]
            keep = r < 1.0
            if not np.any(keep):
                continue
            near, r = near[keep], r[keep]
            w = 1.0 - 3.0 * r**2 + 2.0 * r**3
            local = (d[i] - self.distorted[near]) / self._radius[near, None]
            basis = _monomials(local, 2)  # (k, 6)
            values = np.einsum("kc,kdc->kd", basis, self._fits[near])  # displacement per local fit
            total[i] = w @ values
            weight[i] = w.sum()
        out = self.fallback.correct_points(d)
        inside = weight > 1e-12
        out[inside] = d[inside] + total[inside] / weight[inside, None]
        return out

    def to_dict(self) -> dict:
        return {"model": "local", "neighbours": self.neighbours, "distorted_px": self.distorted.tolist(),
                "ideal_px": self.ideal.tolist(), "fallback": self.fallback.to_dict()}


@dataclass
class OpenCVCorrection(Correction):
    """OpenCV's lens model (k1 k2 p1 p2 [k3 ...]) with its camera matrix (MayaCam 2.0 undistortion)."""

    camera_matrix: np.ndarray
    coefficients: np.ndarray

    def correct_points(self, uv) -> np.ndarray:
        d = np.atleast_2d(np.asarray(uv, dtype=np.float64)).reshape(-1, 1, 2)
        K = np.asarray(self.camera_matrix, dtype=float)
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
        return cv2.undistortPoints(d, K, np.asarray(self.coefficients, float), R=None, P=K,
                                   criteria=criteria).reshape(-1, 2)

    def distort_points(self, uv, iterations: int = 30) -> np.ndarray:
        ideal = np.atleast_2d(np.asarray(uv, dtype=float))
        K = np.asarray(self.camera_matrix, dtype=float)
        x = (ideal - K[:2, 2]) / np.diag(K)[:2]
        points = np.column_stack([x, np.ones(len(x))])
        out, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), K, np.asarray(self.coefficients, float))
        return out.reshape(-1, 2)

    def to_dict(self) -> dict:
        return {"model": "opencv", "camera_matrix": np.asarray(self.camera_matrix).tolist(),
                "coefficients": np.asarray(self.coefficients).tolist()}


def correction_from_dict(d: dict) -> Correction:
    """A correction from ``to_dict`` output (or a MayaCam 2.0 undistortion entry)."""
    try:
        model = d["model"]
        if model == "polynomial":
            return PolynomialCorrection(tuple(d["centre_px"]), float(d["scale_px"]), int(d["degree"]),
                                        np.asarray(d["coef_u"], float), np.asarray(d["coef_v"], float))
        if model == "local":
            return LocalCorrection(np.asarray(d["distorted_px"], float), np.asarray(d["ideal_px"], float),
                                   int(d["neighbours"]), correction_from_dict(d["fallback"]))
        if model == "opencv":
            return OpenCVCorrection(np.asarray(d["camera_matrix"], float), np.asarray(d["coefficients"], float))
    except (KeyError, TypeError, ValueError) as exc:
        raise DistortionError(f"malformed distortion correction ({exc})") from None
    raise DistortionError(f"unknown distortion model {d.get('model')!r}")


# -- plate calibration ---------------------------------------------------------------------------
def detect_holes(image: np.ndarray) -> np.ndarray:
    """Sub-pixel centres (N, 2) of the holes of a perforated-plate image (either polarity)."""
    img = np.asarray(image, dtype=np.float32)
    smooth = cv2.GaussianBlur(img, (0, 0), 1.0)
    scaled = cv2.normalize(smooth, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    level, _ = cv2.threshold(scaled, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    best = np.zeros((0, 2))
    for bright in (True, False):
        mask = (scaled > level) if bright else (scaled <= level)
        centres = _blob_centres(img if bright else img.max() - img, mask.astype(np.uint8))
        if len(centres) > len(best):
            best = centres
    return best


def _blob_centres(img: np.ndarray, mask: np.ndarray) -> np.ndarray:
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    h, w = mask.shape
    stats = stats[1:]
    if len(stats) == 0:
        return np.zeros((0, 2))
    x, y, bw, bh, area = stats.T
    inside = (x > 0) & (y > 0) & (x + bw < w) & (y + bh < h) & (area >= 4)
    if not np.any(inside):
        return np.zeros((0, 2))
    typical = np.median(area[inside])
    fill = area / np.maximum(bw * bh, 1)
    aspect = bw / np.maximum(bh, 1)
    keep = inside & (area > 0.4 * typical) & (area < 2.5 * typical) & (fill > 0.5) & (aspect > 0.5) & (aspect < 2.0)
    background = float(np.median(img[mask == 0])) if np.any(mask == 0) else 0.0
    centres = []
    for k in np.flatnonzero(keep):
        x0, y0 = max(x[k] - 2, 0), max(y[k] - 2, 0)
        x1, y1 = min(x[k] + bw[k] + 2, w), min(y[k] + bh[k] + 2, h)
        patch = np.clip(img[y0:y1, x0:x1] - background, 0.0, None)
        own = (labels[y0:y1, x0:x1] == k + 1) | (labels[y0:y1, x0:x1] == 0)  # not a neighbour's pixels
        patch = patch * own
        total = patch.sum()
        if total <= 0:
            continue
        vv, uu = np.mgrid[y0:y1, x0:x1]
        centres.append(((patch * uu).sum() / total, (patch * vv).sum() / total))
    return np.array(centres, dtype=float).reshape(-1, 2)


def index_grid(centres: np.ndarray, image_size, grid: str = "square") -> tuple[np.ndarray, np.ndarray]:
    """Lattice indices (M, 2) of the holes that fit the grid, and their positions in ``centres``."""
    if grid not in GRID_ANGLES:
        raise DistortionError(f"grid must be 'square' or 'hex', not {grid!r}")
    if len(centres) < MIN_HOLES:
        raise DistortionError(f"no grid of holes found: {len(centres)} hole-like blobs (need at least {MIN_HOLES})")
    tree = cKDTree(centres)
    nn = tree.query(centres, k=2)[0][:, 1]
    spacing = float(np.median(nn))
    centre = (np.asarray(image_size, dtype=float) - 1) / 2.0
    start = int(tree.query(centre)[1])
    near = [i for i in tree.query_ball_point(centres[start], 1.3 * spacing) if i != start]
    vectors = centres[near] - centres[start]
    if len(vectors) < 2:
        raise DistortionError("no grid of holes found: the central hole has no neighbours at the common spacing")
    a = vectors[np.argmax(vectors[:, 0] / np.linalg.norm(vectors, axis=1))]
    best_b, best_error = None, np.inf
    for sign in (1.0, -1.0):
        t = np.radians(sign * GRID_ANGLES[grid])
        expected = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]]) @ a
        k = int(np.argmin(np.linalg.norm(vectors - expected, axis=1)))
        error = float(np.linalg.norm(vectors[k] - expected))
        if error < best_error:
            best_b, best_error = vectors[k], error
    if best_error > 0.25 * spacing:
        raise DistortionError(f"no {grid} grid of holes found: the holes around the centre are not "
                              f"{GRID_ANGLES[grid]:g} degrees apart")
    b = best_b
    index_of = {(0, 0): start}
    position = {start: (0, 0)}
    queue = deque([start])
    while queue:
        h = queue.popleft()
        i, j = position[h]
        local_a = _local_step(index_of, centres, i, j, step=(1, 0), default=a)
        local_b = _local_step(index_of, centres, i, j, step=(0, 1), default=b)
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            key = (i + di, j + dj)
            if key in index_of:
                continue
            guess = centres[h] + di * local_a + dj * local_b
            dist, k = tree.query(guess)
            if dist < 0.3 * spacing and k not in position:
                index_of[key] = int(k)
                position[int(k)] = key
                queue.append(int(k))
    if len(position) < MIN_HOLES:
        raise DistortionError(f"no grid of holes found: only {len(position)} holes lie on one lattice")
    members = np.array(sorted(position), dtype=int)
    indices = np.array([position[m] for m in members], dtype=float)
    return indices, members


def _local_step(index_of, centres, i, j, *, step, default):
    di, dj = step
    here = index_of.get((i, j))
    ahead, behind = index_of.get((i + di, j + dj)), index_of.get((i - di, j - dj))
    if ahead is not None:
        return centres[ahead] - centres[here]
    if behind is not None:
        return centres[here] - centres[behind]
    return default


@dataclass
class PlateFit:
    """A plate calibration: the correction and its residual per hole (px and mm)."""

    correction: Correction
    polynomial: PolynomialCorrection
    holes_px: np.ndarray  # (N, 2) detected centres used
    indices: np.ndarray  # (N, 2) lattice indices
    ideal_px: np.ndarray  # (N, 2) ideal grid positions
    residual_px: np.ndarray  # (N,) |corrected - ideal|
    mm_per_px: float
    discarded: int
    grid: str
    spacing_mm: float
    left_out_px: np.ndarray | None = None  # local model: residual at each hole predicted without it

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.residual_px**2)))

    @property
    def max_px(self) -> float:
        return float(self.residual_px.max())

    def summary(self) -> dict:
        out = {"holes": int(len(self.holes_px)), "discarded": int(self.discarded), "grid": self.grid,
               "spacing_mm": self.spacing_mm, "mm_per_px": self.mm_per_px,
               "rms_px": self.rms_px, "max_px": self.max_px,
               "rms_mm": self.rms_px * self.mm_per_px, "max_mm": self.max_px * self.mm_per_px}
        if self.left_out_px is not None:
            out["left_out_rms_px"] = float(np.sqrt(np.mean(self.left_out_px**2)))
            out["left_out_max_px"] = float(self.left_out_px.max())
        return out


def fit_plate(image: np.ndarray, spacing_mm: float, *, grid: str = "square", model: str = "global",
              degree: int = 5, neighbours: int = 12, progress=None) -> PlateFit:
    """Detect, index and fit: the correction of a plate image (see the module docstring)."""
    if spacing_mm <= 0:
        raise DistortionError("the hole spacing must be positive")
    if model not in ("global", "local"):
        raise DistortionError(f"model must be 'global' or 'local', not {model!r}")
    image = np.asarray(image, dtype=np.float32)
    h, w = image.shape
    centres = detect_holes(image)
    if progress:
        progress(f"{len(centres)} holes detected")
    indices, members = index_grid(centres, (w, h), grid)
    holes = centres[members]
    polynomial, ideal = _fit_global(holes, indices, (w, h), grid, degree=degree)
    correction: Correction = polynomial
    left_out = None
    if model == "local":
        correction = LocalCorrection(holes, ideal, neighbours, polynomial)
        left_out = correction.left_out_residuals()
    residual = np.linalg.norm(correction.correct_points(holes) - ideal, axis=1)
    step_px = _lattice_step_px(ideal, indices)
    return PlateFit(correction, polynomial, holes, indices, ideal, residual, spacing_mm / step_px,
                    len(centres) - len(members), grid, float(spacing_mm), left_out)


def _lattice_step_px(ideal: np.ndarray, indices: np.ndarray) -> float:
    A = np.column_stack([np.ones(len(indices)), indices])
    coef = np.linalg.lstsq(A, ideal, rcond=None)[0]
    return float(np.linalg.norm(coef[1]))


def _fit_global(holes, indices, image_size, grid, *, degree):
    """Joint least squares of the ideal lattice (origin, a; b = a turned) and the polynomial."""
    centre = (np.asarray(image_size, dtype=float) - 1) / 2.0
    scale = float(max(image_size)) / 2.0
    # orientation of b relative to a, from the indexed holes (b = M a, M a turn by +-angle)
    A0 = np.column_stack([np.ones(len(indices)), indices])
    rough = np.linalg.lstsq(A0, holes, rcond=None)[0]
    cross = rough[1, 0] * rough[2, 1] - rough[1, 1] * rough[2, 0]
    t = np.radians(np.sign(cross) * GRID_ANGLES[grid])
    M = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    basis = _monomials((holes - centre) / scale, degree, 2)
    n, k = len(holes), basis.shape[1]
    i, j = indices[:, 0], indices[:, 1]
    # unknowns: o_u, o_v, p, q, coef_u (k), coef_v (k);  ideal = o + i a + j M a,  a = (p, q)
    rows_u = np.column_stack([np.ones(n), np.zeros(n), i + j * M[0, 0], j * M[0, 1], -scale * basis, np.zeros((n, k))])
    rows_v = np.column_stack([np.zeros(n), np.ones(n), j * M[1, 0], i + j * M[1, 1], np.zeros((n, k)), -scale * basis])
    system = np.vstack([rows_u, rows_v])
    rhs = np.concatenate([holes[:, 0], holes[:, 1]])
    if n * 2 < system.shape[1] + 4:
        raise DistortionError(f"too few holes ({n}) for a degree-{degree} polynomial")
    solution = np.linalg.lstsq(system, rhs, rcond=None)[0]
    origin, a = solution[:2], solution[2:4]
    ideal = origin + i[:, None] * a + j[:, None] * (M @ a)
    poly = PolynomialCorrection((float(centre[0]), float(centre[1])), scale, degree,
                                solution[4:4 + k], solution[4 + k:])
    return poly, ideal


def residual_picture(image: np.ndarray, fit: PlateFit, gain: float = 20.0) -> np.ndarray:
    """An RGB uint8 picture: the plate, each used hole coloured by its residual (green
    below 0.1 px, yellow below 0.5 px, red above) and its residual vector drawn ``gain``
    times longer."""
    img = np.asarray(image, dtype=np.float32)
    gray = cv2.normalize(img, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    out = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    corrected = fit.correction.correct_points(fit.holes_px)
    for hole, moved, ideal, r in zip(fit.holes_px, corrected, fit.ideal_px, fit.residual_px):
        colour = (0, 200, 0) if r < 0.1 else (0, 220, 255) if r < 0.5 else (0, 0, 255)
        p = tuple(int(round(c)) for c in hole)
        tip = tuple(int(round(c)) for c in hole + gain * (moved - ideal))
        cv2.circle(out, p, 3, colour, 1, cv2.LINE_AA)
        cv2.line(out, p, tip, colour, 1, cv2.LINE_AA)
    return out[..., ::-1].copy()  # RGB
