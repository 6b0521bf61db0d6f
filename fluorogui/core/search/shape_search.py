"""Fast coarse pose search of an implant model in two X-ray images (used by ``find``).

No segmentation is trusted here: thresholded dark regions only propose where a
component might be. Poses are scored on *oriented edge maps*: a projected outline point
with outward normal ``n`` scores ``clip(grad(I) . n / g_ref, -1, 1)`` (metal is dark, so
the intensity rises outwards across a true outline; ``g_ref`` is a quarter of the
strong-edge gradient of the view). The mean over the outline and over both views is the
*edge score* (0.8-1 at a right pose on the real data; wrong orientations mostly score
under 0.6, a flipped tibial tray about 0.75).

Speed comes from three things:

- ``ShapeLibrary``: the outer silhouette of the (decimated) mesh seen along 1000 evenly
  spread directions, each kept as 32 outline points and normals in a plane frame. For a
  rotation R and a point c, the view's ray through c gives the viewing direction in
  model coordinates (nearest template), and the view's projection Jacobian at c maps the
  template plane onto pixels (rotation, scale and the small off-axis shear in one 2x2
  matrix). Thousands of orientations are then placed with a few array operations; it is
  built once per mesh (0.5-1 s) and cached.
- ``EdgeMaps``: the oriented scores are precomputed per view for 16 normal directions at
  quarter resolution (blurred: a wide basin) and half resolution (sharper), padded so
  that a 2D shift is a constant offset into the flat array: scoring N orientations x S
  shifts x K points is one gather.
- ``refine_on_edges``: from a coarse pose, a few Gauss-Newton steps on exact silhouettes
  of a decimated mesh (a few thousand faces instead of ~50k), each outline point pulled
  to the strongest dark-inside edge found along its normal (RAPiD-style tracking), with
  a search radius shrinking from 20 to 3 px.
"""
from __future__ import annotations

import copy
import dataclasses
import threading
import weakref
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from fluorogui.core.matching.problem import visible_points
from fluorogui.core.outlines.field import field_of_view, image_unit, to_unit_float
from fluorogui.core.outlines.spline import outward_normals
from fluorogui.core.projection.facing import facing_edges
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh, prepare_mesh

N_BINS = 16  # quantised normal directions of the oriented edge maps (a power of two: EdgeMaps.index)
PAD = 40  # padding (pixels of a map level) so shifted look-ups never leave the array
LEVELS = {"coarse": (0.25, 2.0), "fine": (0.5, 1.2)}  # name -> (scale of a 1024-px image, blur sigma in map px)


# -- a small mesh for silhouettes --------------------------------------------------------------
def decimate_mesh(mesh: PreparedMesh, target_faces: int = 6000) -> PreparedMesh:
    """Vertex-clustering decimation (grid cells, vertices of a cell merged at their mean)
    to about ``target_faces`` faces. Its silhouette differs from the full mesh's by a
    fraction of a millimetre (IoU ~0.99 at half resolution), and silhouettes of it cost a
    tenth. The result need not be manifold: edges used by more than two faces become
    ``open_edges``, which are always drawn; they lie inside the projection, so the outer
    outline is unaffected."""
    if len(mesh.faces) <= target_faces:
        return dataclasses.replace(mesh)  # a new object sharing the arrays (see shape_library)
    v, f = mesh.vertices, mesh.faces
    cell = np.sqrt(mesh.area / target_faces) * 1.25
    best = mesh
    for _ in range(6):  # a few adjustments of the cell size towards the target
        g = np.floor((v - v.min(0)) / cell).astype(np.int64)
        key = (g[:, 0] * 1_000_003 + g[:, 1]) * 1_000_003 + g[:, 2]
        _, inv = np.unique(key, return_inverse=True)
        count = np.bincount(inv)
        nv = np.column_stack([np.bincount(inv, v[:, k]) for k in range(3)]) / count[:, None]
        nf = inv[f]
        ok = (nf[:, 0] != nf[:, 1]) & (nf[:, 1] != nf[:, 2]) & (nf[:, 0] != nf[:, 2])
        nf = nf[ok]
        _, first = np.unique(np.sort(nf, axis=1), axis=0, return_index=True)
        nf = nf[np.sort(first)]
        best = prepare_mesh(nv, nf)
        ratio = len(nf) / target_faces
        if 0.7 < ratio < 1.4:
            break
        cell *= np.sqrt(ratio)
    return best


def sphere_directions(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere (Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5 ** 0.5) * i
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def draw_segments(canvas: np.ndarray, segments: np.ndarray) -> None:
    """Set to 1 the pixels of ``canvas`` (uint8, C order) that
    ``cv2.polylines(canvas, segments, False, 1, 1, cv2.LINE_8, 4)`` sets, for line segments
    (S, 2, 2) int32 in 1/16 pixel: every segment in one pass of array operations, where
    OpenCV's per-segment setup was most of its time (0.25 -> 0.18 ms for the ~830
    silhouette edges of a search outline; tests/core/test_find.py compares the two).

    OpenCV rounds the ends to pixels ((v + 8) >> 4) and draws 8-connected Bresenham lines
    from the left end: pixel ``i`` along the longer axis (ties: x) is ``m_i`` pixels along
    the shorter one, ``m_i = floor((2 minor i + major - 1) / (2 major))`` (the error term
    ``major - 2 minor (i + 1) + 2 major m_i`` stays in ``[-2 minor, 2 major - 2 minor)``).
    Ends off the canvas (never, for the outlines here) are left to OpenCV, which clips."""
    if not len(segments):
        return
    h, w = canvas.shape
    p = (np.asarray(segments, np.int32) + 8) >> 4
    if p.min() < 0 or p[..., 0].max() >= w or p[..., 1].max() >= h:
        cv2.polylines(canvas, segments, False, 1, 1, cv2.LINE_8, 4)
        return
    x0, y0, x1, y1 = p[:, 0, 0], p[:, 0, 1], p[:, 1, 0], p[:, 1, 1]
    swap = x1 < x0  # from the left end
    x, y = np.where(swap, x1, x0), np.where(swap, y1, y0)
    dx, dy = np.abs(x1 - x0), np.where(swap, y0 - y1, y1 - y0)
    y_step = np.where(dy < 0, -w, w).astype(np.int32)
    dy = np.abs(dy)
    steep = dy > dx
    major, minor = np.where(steep, dy, dx), np.where(steep, dx, dy)
    count = major + 1
    start = np.cumsum(count) - count
    i = np.arange(int(start[-1] + count[-1]), dtype=np.int32) - np.repeat(start.astype(np.int32), count)
    m = (i * np.repeat(2 * minor, count) + np.repeat(np.maximum(major - 1, 0), count)) // np.repeat(
        np.maximum(2 * major, 1), count)
    flat = (np.repeat(y * w + x, count) + i * np.repeat(np.where(steep, y_step, 1).astype(np.int32), count)
            + m * np.repeat(np.where(steep, 1, y_step).astype(np.int32), count))
    canvas.ravel()[flat] = 1


def _smooth_closed(p: np.ndarray, k: int) -> np.ndarray:
    """Moving average over 2k+1 points of a closed polyline."""
    if len(p) < 2 * k + 2:
        return p
    c = np.cumsum(np.vstack([p[-k - 1:], p, p[:k]]), axis=0)
    return (c[2 * k + 1:] - c[:-2 * k - 1]) / (2 * k + 1)


def _closed_resample(p: np.ndarray, k: int) -> np.ndarray:
    seg = np.linalg.norm(np.diff(np.vstack([p, p[:1]]), axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])  # (np.r_ took most of the time of these small arrays)
    t = (np.arange(k) + 0.5) * s[-1] / k
    return np.column_stack([np.interp(t, s, np.append(p[:, 0], p[0, 0])), np.interp(t, s, np.append(p[:, 1], p[0, 1]))])


# -- silhouettes along many directions ----------------------------------------------------------
@dataclass
class ShapeLibrary:
    """Outer silhouettes of a mesh seen along ``directions`` (model frame) from a point
    ``distance`` mm away from the centroid. Outline ``points`` (n, K, 2) are in mm on the
    plane through the centroid, in the frame (``a``, ``b``) of each direction, relative to
    the centroid's projection; ``normals`` are the outward unit normals there."""

    centroid: np.ndarray  # of the full mesh (the library holds no reference to it: see shape_library)
    coarse: PreparedMesh  # ~4000 faces: templates, screening
    fine: PreparedMesh  # ~15000 faces: finishing the refinement
    directions: np.ndarray
    a: np.ndarray
    b: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    tree: cKDTree  # of the directions

    @classmethod
    def build(cls, mesh: PreparedMesh, *, n_directions: int = 1000, n_points: int = 32,
              distance: float = 1000.0, resolution_mm: float = 0.5) -> "ShapeLibrary":
        coarse = decimate_mesh(mesh, 4000)
        d = sphere_directions(n_directions)
        hint = np.where(np.abs(d[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
        a = np.cross(d, hint)
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        b = np.cross(d, a)
        c = mesh.centroid
        V = coarse.vertices - c
        # every direction at once: the source is at -distance * d from the centroid. (The
        # (faces, n) and (n, V) arrays are tens of MB: each made once and worked on in place,
        # and the plane's two coordinates kept apart, so that their extremes are row reductions)
        toward = np.matmul(coarse.face_normals, d.T)
        toward *= distance
        front = np.subtract((coarse.face_normals @ c - coarse.face_offsets)[:, None], toward, out=toward) > 0
        on = (front[coarse.edge_faces[:, 0]] != front[coarse.edge_faces[:, 1]]).T.copy()  # (n, E): silhouette edges
        depth = d @ V.T + distance  # (n, V): along each direction from its source
        ratio = np.divide(distance, depth, out=depth)
        xy = [np.multiply(e @ V.T, ratio, out=ratio if k else None) for k, e in enumerate((a, b))]  # on the plane
        points = np.zeros((n_directions, n_points, 2))
        lo = np.column_stack([x.min(axis=1) for x in xy]) - 2.0  # every vertex projects inside: its bounding box
        size = (np.ceil((np.column_stack([x.max(axis=1) for x in xy]) - lo + 2.0) / resolution_mm) + 1).astype(int)
        fixed = np.empty(xy[0].shape + (2,), np.int32)
        for k, x in enumerate(xy):
            x -= lo[:, k:k + 1]
            x *= 16 / resolution_mm
            fixed[..., k] = np.round(x, out=x)
        for j in range(n_directions):
            edges = np.vstack([coarse.edges[on[j]], coarse.open_edges])
            canvas = np.zeros((size[j, 1], size[j, 0]), np.uint8)
            draw_segments(canvas, fixed[j][edges])
            contours, _ = cv2.findContours(canvas, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
            outer = max(contours, key=len)
            o = _smooth_closed(outer[:, 0, :] * resolution_mm + lo[j], 2)  # drop the pixel staircase
            points[j] = _closed_resample(o, n_points)
        normals = outward_normals(points)  # of all outlines at once
        return cls(mesh.centroid.copy(), coarse, decimate_mesh(mesh, 15000), d, a, b, points, normals, cKDTree(d))


_LIBRARIES: dict[int, tuple[weakref.ref, ShapeLibrary]] = {}
_LIBRARY_LOCK = threading.Lock()


def shape_library(mesh: PreparedMesh) -> ShapeLibrary:
    """The ShapeLibrary of ``mesh``, built on first use (~0.5-1 s) and kept while the
    mesh object lives (thread-safe)."""
    with _LIBRARY_LOCK:
        hit = _LIBRARIES.get(id(mesh))
        if hit is not None and hit[0]() is mesh:
            return hit[1]
        lib = ShapeLibrary.build(mesh)
        for k in [k for k, (ref, _) in _LIBRARIES.items() if ref() is None]:
            del _LIBRARIES[k]
        _LIBRARIES[id(mesh)] = (weakref.ref(mesh), lib)
        return lib


# -- oriented edge maps ---------------------------------------------------------------------------
_FRAME_MAPS: list = []  # [(images, fields of view, maps)]: the last frame's (edge_maps_of)
_FRAME_LOCK = threading.Lock()


def edge_maps_of(images) -> tuple[list[np.ndarray], list["EdgeMaps"]]:
    """The fields of view and ``EdgeMaps`` of a frame's images, made once per set of image
    arrays (compared by identity, and held so their ids stay theirs): recovery searches
    near each component of a frame, and a search of the whole image may follow, on the same
    images (each set of maps took 0.1-0.2 s of a 0.4-0.5 s search on the real frames)."""
    images = list(images)
    with _FRAME_LOCK:
        if _FRAME_MAPS and len(_FRAME_MAPS[0][0]) == len(images) and all(
                a is b for a, b in zip(_FRAME_MAPS[0][0], images)):
            return list(_FRAME_MAPS[0][1]), list(_FRAME_MAPS[0][2])
    fovs = [field_of_view(image) for image in images]
    maps = [EdgeMaps(image, fov) for image, fov in zip(images, fovs)]
    with _FRAME_LOCK:
        _FRAME_MAPS[:] = [(images, fovs, maps)]
    return list(fovs), list(maps)


class EdgeMaps:
    """Oriented edge scores of one image at the ``LEVELS`` resolutions, and its gradients
    at half resolution (of a 1024-pixel image: ``work`` scale) for ``refine_on_edges``.
    ``fov`` (full resolution, bool) limits where the strong-edge reference gradient is
    measured."""

    def __init__(self, image: np.ndarray, fov: np.ndarray | None = None, kappa: float = 0.25):
        img = to_unit_float(image)
        self.shape = img.shape
        self.unit = image_unit(img.shape)
        self.work = 0.5 / self.unit
        half = cv2.resize(img, None, fx=self.work, fy=self.work, interpolation=cv2.INTER_AREA)
        g = cv2.GaussianBlur(half, (0, 0), 1.0)
        self.gx = cv2.Sobel(g, cv2.CV_32F, 1, 0) / 8.0
        self.gy = cv2.Sobel(g, cv2.CV_32F, 0, 1) / 8.0
        mag = np.hypot(self.gx, self.gy)
        inside = np.ones(mag.shape, bool)
        if fov is not None:
            inside = cv2.resize(np.asarray(fov, np.uint8), mag.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
            inside = cv2.erode(inside.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
        vals = mag[inside] if inside.any() else mag.ravel()
        self.g_ref = max(float(np.percentile(vals, 99.5)) * kappa, 1e-6)  # per work pixel
        self.levels = {}
        theta = 2 * np.pi * np.arange(N_BINS) / N_BINS
        for name, (scale, sigma) in LEVELS.items():
            scale = scale / self.unit
            small = half if scale == self.work else cv2.resize(img, None, fx=scale, fy=scale,
                                                               interpolation=cv2.INTER_AREA)
            s = cv2.GaussianBlur(small, (0, 0), sigma)
            gx = cv2.Sobel(s, cv2.CV_32F, 1, 0) / 8.0
            gy = cv2.Sobel(s, cv2.CV_32F, 0, 1) / 8.0
            ref = self.g_ref * (scale / self.work)  # gradients per map pixel scale with the pixel size
            maps = np.zeros((N_BINS, s.shape[0] + 2 * PAD, s.shape[1] + 2 * PAD), np.int8)  # score x 127
            # clip((gx cos t + gy sin t) * 127 / ref), rounded, in float64 as the float64 cos and
            # sin make it; the gradients widened once and every step in place (a third faster)
            gx64, gy64 = gx.astype(np.float64), gy.astype(np.float64)
            v, w = np.empty_like(gx64), np.empty_like(gx64)
            for k, t in enumerate(theta):
                np.multiply(gx64, np.cos(t), out=v)
                v += np.multiply(gy64, np.sin(t), out=w)
                v *= 127.0 / ref
                np.rint(np.clip(v, -127.0, 127.0, out=v), out=v)
                maps[k, PAD:-PAD, PAD:-PAD] = v
            self.levels[name] = (scale, maps.ravel(), maps.shape[1], maps.shape[2], s.shape)

    def with_hidden(self, hidden: np.ndarray | None, neutral: float) -> "EdgeMaps":
        """These maps with the pixels under ``hidden`` (full resolution, bool: where another
        component lies) scoring ``neutral`` in every direction: an outline passing behind it
        is neither rewarded by its edges nor punished for the edges it hides."""
        if hidden is None or not np.any(hidden):
            return self
        out = copy.copy(self)
        out.levels = {}
        value = np.int8(round(127 * neutral))
        for name, (scale, flat, H, W, (h, w)) in self.levels.items():
            maps = flat.reshape(-1, H, W).copy()
            small = cv2.resize(np.asarray(hidden, np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
            maps[:, PAD:PAD + h, PAD:PAD + w][:, small] = value
            out.levels[name] = (scale, maps.ravel(), H, W, (h, w))
        return out

    def index(self, level: str, points_px: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Flat look-up indices of full-resolution points with their normals."""
        scale, _, H, W, (h, w) = self.levels[level]
        # (b H + y) W + x of the rounded, clipped point and normal direction bin; each step in
        # place (a quarter of the time of fresh arrays), the bin's modulo a mask (N_BINS is a
        # power of two: the same for negative numbers too)
        q = points_px * scale
        q += (scale - 1.0) / 2.0
        np.rint(q, out=q)
        x = np.clip(q[..., 0], -PAD // 2, w + PAD // 2).astype(np.int64)
        y = np.clip(q[..., 1], -PAD // 2, h + PAD // 2).astype(np.int64)
        turn = np.arctan2(normals[..., 1], normals[..., 0])
        turn *= N_BINS / (2 * np.pi)
        b = np.rint(turn, out=turn).astype(np.int64)
        b &= N_BINS - 1
        b *= H
        y += PAD
        b += y
        b *= W
        x += PAD
        b += x
        return b

    def offsets(self, level: str, shifts_px: np.ndarray) -> np.ndarray:
        """Flat offsets of full-resolution 2D shifts (rounded to map pixels)."""
        scale, _, _, W, _ = self.levels[level]
        s = np.rint(np.asarray(shifts_px, float) * scale).astype(np.intp)
        return s[:, 1] * W + s[:, 0]

    def mean_score(self, level: str, idx: np.ndarray) -> np.ndarray:
        """Mean score over the last axis of look-up indices (np.take on int8 maps is several
        times faster than fancy indexing of float32 ones)."""
        v = np.take(self.levels[level][1], idx)
        return v.sum(-1, dtype=np.int32) * (1.0 / (127.0 * idx.shape[-1]))

    def shifted_scores(self, level: str, idx: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """Mean scores (N, S) of outlines ``idx`` (N, K) moved by every flat offset (S,);
        one shift at a time, which keeps the index array small."""
        flat = self.levels[level][1]
        out = np.empty((len(offsets), len(idx)), np.int32)
        moved = np.empty(idx.shape, idx.dtype)
        for s, o in enumerate(offsets):
            np.add(idx, o, out=moved)
            out[s] = np.take(flat, moved).sum(-1, dtype=np.int32)
        return out.T * (1.0 / (127.0 * idx.shape[-1]))


def edge_score(maps: EdgeMaps, points_px: np.ndarray, normals: np.ndarray, level: str = "fine") -> float:
    """Mean oriented edge score of one outline (points with outward normals) in one view."""
    return float(maps.mean_score(level, maps.index(level, points_px, normals)))


# -- placing templates ------------------------------------------------------------------------
def place_templates(lib: ShapeLibrary, view: View, rotations: np.ndarray, centre: np.ndarray):
    """Template outlines of ``rotations`` (N, 3, 3) with the model centroid at ``centre``
    (world, mm; one (3,) or one per rotation (N, 3)) in ``view``: pixel points (N, K, 2)
    and outward normals (N, K, 2)."""
    centres = np.broadcast_to(np.asarray(centre, float), (len(rotations), 3))
    r = centres - view.source
    r = r / np.linalg.norm(r, axis=1, keepdims=True)
    d = np.einsum("nji,nj->ni", rotations, r)  # the ray in model coordinates
    _, j = lib.tree.query(d)
    if centre.ndim == 1:
        uv, J = view.project_jacobian(centre[None, :])
    else:
        uv, J = view.project_jacobian(centres)
    JR = np.matmul(J, rotations)  # (N, 2, 3): d(pixel)/d(model vector)
    M = np.matmul(JR, np.stack([lib.a[j], lib.b[j]], axis=-1))  # (N, 2, 2): template plane -> pixels
    pts = uv[:, None, :] + np.matmul(lib.points[j], M.transpose(0, 2, 1))
    # normals map with the inverse transpose; the cofactor matrix is that up to a positive factor
    cof = np.empty_like(M)
    cof[:, 0, 0], cof[:, 0, 1], cof[:, 1, 0], cof[:, 1, 1] = M[:, 1, 1], -M[:, 1, 0], -M[:, 0, 1], M[:, 0, 0]
    cof *= np.sign(M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] * M[:, 1, 0])[:, None, None]
    nrm = np.matmul(lib.normals[j], cof.transpose(0, 2, 1))
    return pts, nrm


def scan_orientations(lib: ShapeLibrary, views, maps, centre: np.ndarray, *, rotations: np.ndarray,
                      shifts_px: np.ndarray, level: str = "coarse", chunk: int = 1000):
    """Edge score of every rotation with the centroid near ``centre`` ((3,), or (N, 3): one
    per rotation): per view the best of the 2D ``shifts_px`` (S, 2; px of a 1024-pixel
    image) is taken. Returns the mean score over views (N,) and the best shift per view
    in that view's pixels (N, V, 2)."""
    n = len(rotations)
    total = np.zeros(n)
    best = np.zeros((n, len(views), 2))
    centre = np.asarray(centre, float)
    for k, (view, m) in enumerate(zip(views, maps)):
        shifts = np.asarray(shifts_px, float) * m.unit
        off = m.offsets(level, shifts)
        for s in range(0, n, chunk):
            pts, nrm = place_templates(lib, view, rotations[s:s + chunk],
                                       centre if centre.ndim == 1 else centre[s:s + chunk])
            sc = m.shifted_scores(level, m.index(level, pts, nrm), off)
            arg = sc.argmax(1)
            total[s:s + chunk] += sc[np.arange(len(arg)), arg] / len(views)
            best[s:s + chunk, k] = shifts[arg]
    return total, best


def rescore(lib: ShapeLibrary, views, maps, centre: np.ndarray, *, rotations: np.ndarray, shifts: np.ndarray,
            local_px: np.ndarray, level: str = "fine"):
    """Score rotations again on a sharper map level, each view searching ``local_px``
    (S, 2; px of a 1024-pixel image) around the rotation's own shift ``shifts`` (N, V, 2;
    that view's pixels). Returns the scores (N,) and the new shifts (N, V, 2)."""
    total = np.zeros(len(rotations))
    best = np.zeros_like(shifts)
    for k, (view, m) in enumerate(zip(views, maps)):
        local = np.asarray(local_px, float) * m.unit
        pts, nrm = place_templates(lib, view, rotations, centre)
        sc = m.shifted_scores(level, m.index(level, pts + shifts[:, k][:, None, :], nrm), m.offsets(level, local))
        arg = sc.argmax(1)
        total += sc[np.arange(len(arg)), arg] / len(views)
        best[:, k] = shifts[:, k] + local[arg]
    return total, best


def shift_grid(radius_px: float, step_px: float) -> np.ndarray:
    g = np.arange(-radius_px, radius_px + 1e-9, step_px)
    return np.array([(x, y) for y in g for x in g], float)


# -- exact silhouettes and refinement on edges ---------------------------------------------------------
def outline(mesh: PreparedMesh, R: np.ndarray, c: np.ndarray, view: View, *, spacing_px: float = 4.0,
            nearest: bool = True):
    """Outer outline of ``mesh`` with rotation R and centroid at c in ``view``: pixel
    points about ``spacing_px`` apart, their outward normals, and for each the model
    vertex (an end of a silhouette edge) nearest to it in the image, which is what the
    point images to within an edge length (enough for Gauss-Newton steps; None unless
    ``nearest``: a score needs only the points)."""
    t = c - R @ mesh.centroid
    # the silhouette edges with the vertices they use (sorted) and their ends among those,
    # as the facing cache already keeps them
    found = facing_edges(mesh, R.T @ (np.asarray(view.source, dtype=float) - t))
    if len(found.edges) == 0:
        raise ValueError("the mesh has no silhouette from this source")
    ends, local = found.ends, found.local
    X = mesh.vertices[ends] @ R.T + t
    if np.any((X - view.source) @ view.normal <= 1e-6):
        raise ValueError("part of the model lies behind the X-ray source")
    uv = view.project(X)
    lo = np.floor(uv.min(0)) - 2.0
    size = (np.ceil(uv.max(0) - lo) + 3).astype(int)
    if size.max() > 8192:
        raise ValueError("the model is too close to the X-ray source")
    canvas = np.zeros((size[1], size[0]), np.uint8)
    segs = np.round((uv - lo) * 16).astype(np.int32)[local]
    draw_segments(canvas, segs)
    contours, _ = cv2.findContours(canvas, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    pts = max(contours, key=cv2.contourArea)[:, 0, :].astype(float)
    step = max(1, int(round(spacing_px)))
    pts = _smooth_closed(pts, 2)[::step] + lo
    if len(pts) < 4:
        raise ValueError("the projected model is too small")
    if not nearest:
        return pts, outward_normals(pts), None
    # a tree queried once: unbalanced and not compacted it is built faster and answers the same
    # (the nearest by the same distances; 0.19 instead of 0.23 ms a call on the real frames)
    _, closest = cKDTree(uv, balanced_tree=False, compact_nodes=False).query(pts)
    return pts, outward_normals(pts), mesh.vertices[ends[closest]]


def pose_edge_score(mesh: PreparedMesh, R, c, views, *, maps, level: str = "fine", hidden=None) -> list[float]:
    """Per-view edge score of the exact outline at (R, centroid c); ``hidden`` (per view, a
    boolean image or None) leaves out the outline points another component covers."""
    out = []
    for k, (view, m) in enumerate(zip(views, maps)):
        try:
            p, n, _ = outline(mesh, R, c, view, spacing_px=4.0 * m.unit, nearest=False)
        except ValueError:
            out.append(-1.0)
            continue
        mask = hidden[k] if hidden is not None and k < len(hidden) else None
        if mask is not None:
            seen = visible_points(mask, p)
            p, n = p[seen], n[seen]
        out.append(edge_score(m, p, n, level))
    return out


def _bilinear(img: np.ndarray, q: np.ndarray) -> np.ndarray:
    return cv2.remap(img, q[..., 0].astype(np.float32), q[..., 1].astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(len(v))
    return np.stack([np.stack([z, -v[:, 2], v[:, 1]], 1), np.stack([v[:, 2], z, -v[:, 0]], 1),
                     np.stack([-v[:, 1], v[:, 0], z], 1)], 1)


def refine_on_edges(mesh: PreparedMesh, views, maps, R: np.ndarray, *, c: np.ndarray,
                    radii_px=(20, 14, 10, 7, 5, 4, 3, 3), min_response: float = 0.15):
    """Gauss-Newton on exact silhouettes: every outline point is pulled to the strongest
    dark-inside edge along its normal within the current radius (px of a 1024-pixel
    image; the search runs on the ``work``-scale gradients). Returns (R, c)."""
    from fluorogui.core.projection.pose import rotvec_matrix  # local: pose imports nothing from here

    rho = max(mesh.radius, 1.0)
    for radius in radii_px:
        H = np.zeros((6, 6))
        g = np.zeros(6)
        used = 0
        for view, m in zip(views, maps):
            try:
                p, n, model = outline(mesh, R, c, view, spacing_px=3.0 * m.unit)
            except ValueError:
                continue
            steps = np.arange(-radius, radius + 1e-9, 1.0) * m.unit  # full-res px along the normal
            q = (p[:, None, :] + steps[None, :, None] * n[:, None, :]) * m.work + (m.work - 1.0) / 2.0
            resp = (_bilinear(m.gx, q) * n[:, None, 0] + _bilinear(m.gy, q) * n[:, None, 1]) / m.g_ref
            k = resp.argmax(1)
            peak = resp[np.arange(len(k)), k]
            ok = peak > min_response
            # sub-sample peak: parabola through the neighbours
            k1 = np.clip(k, 1, len(steps) - 2)
            y0, y1, y2 = (resp[np.arange(len(k)), k1 + d] for d in (-1, 0, 1))
            den = y0 - 2 * y1 + y2
            frac = np.where(np.abs(den) > 1e-9, 0.5 * (y0 - y2) / np.where(np.abs(den) > 1e-9, den, 1.0), 0.0)
            s = steps[k1] + np.clip(frac, -1, 1) * m.unit
            if ok.sum() < 6:
                continue
            X = model[ok] @ R.T + (c - R @ mesh.centroid)
            _, Jp = view.project_jacobian(X)
            nJ = np.einsum("ij,ijk->ik", n[ok], Jp)
            J = np.hstack([nJ, -np.einsum("ik,ikl->il", nJ, _skew(X - c)) / rho])
            r = -s[ok]  # model point minus target along the normal
            huber = 2.0 * m.unit
            w = np.where(np.abs(r) < huber, 1.0, huber / np.abs(r)) * np.minimum(peak[ok], 1.0) / ok.sum()
            H += J.T @ (J * w[:, None])
            g += J.T @ (w * r)
            used += 1
        if used == 0:
            break
        step = np.linalg.solve(H + 1e-3 * np.diag(np.diag(H) + 1e-9), -g)
        c = c + step[:3]
        R = rotvec_matrix(step[3:] / rho) @ R
    return R, c


# -- where to look -------------------------------------------------------------------------------------
@dataclass
class DarkLevels:
    """The dark regions of one image at its grey levels (``dark_levels``): made once and
    read by both rounds of *find implants*' position hypotheses."""

    scale: float  # of the half-size image the regions are in (its pixels to full resolution)
    unit: float  # image_unit of the full image
    regions: list  # per grey level: (opened dark mask, connected-component stats, centroids)


def dark_levels(image: np.ndarray, fov: np.ndarray, *, n_levels: int = 14) -> DarkLevels:
    """The connected regions below each of ``n_levels`` grey levels (the 0.5th to 45th
    percentile inside the field of view ``fov``) of ``image`` at half the size of a
    1024-pixel image, blurred, opened by a 3 x 3 square."""
    img = to_unit_float(image)
    unit = image_unit(img.shape)
    scale = 0.5 / unit  # pixel counts below are those of half a 1024-pixel image
    half = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    s = cv2.GaussianBlur(half, (0, 0), 1.5)
    inside = cv2.resize(np.asarray(fov, np.uint8), s.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
    if not inside.any():
        return DarkLevels(scale, unit, [])
    levels = np.unique(np.percentile(s[inside], np.linspace(0.5, 45.0, n_levels)))
    kernel = np.ones((3, 3), np.uint8)
    regions = []
    for level in levels:
        dark = cv2.morphologyEx(((s <= level) & inside).astype(np.uint8), cv2.MORPH_OPEN, kernel)
        _, _, stats, cents = cv2.connectedComponentsWithStats(dark, connectivity=8)
        regions.append((dark, stats, cents))
    return DarkLevels(scale, unit, regions)


def dark_region_points(image: np.ndarray, fov: np.ndarray, *, n_levels: int = 14, min_area_px: float = 1500.0,
                       max_area_px: float = 150000.0, merge_px: float = 12.0, min_radius_px: float = 24.0,
                       peak_px: int = 30, max_peaks: int = 4,
                       levels: DarkLevels | None = None) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Where dark things are, in full-resolution pixels: (region centroids, depth peaks).

    Metal is darker than its surroundings, but no single grey level separates a tibial
    tray and keel from the bone around them, and a femoral component can merge with dark
    soft tissue. So every connected region below each of ``n_levels`` grey levels (the
    0.5th to 45th percentile inside the field of view) with a plausible area gives its
    centroid; nested regions give their own (a keel alone, a keel with its tray, ...).
    The second list holds local maxima of the distance to the region border (at least
    ``min_radius_px`` deep, ``peak_px`` apart, the ``max_peaks`` deepest per level): a
    component merged with dark soft tissue or the dark rim of the field of view has no
    region of its own but is a thick part of one. Points closer than ``merge_px`` to one
    already listed are dropped. ``levels`` are the image's ``dark_levels`` when already
    made."""
    if levels is None:
        levels = dark_levels(image, fov, n_levels=n_levels)
    scale, unit = levels.scale, levels.unit
    peak_kernel = np.ones((2 * (peak_px // 2) + 1,) * 2, np.uint8)
    centroids: list[np.ndarray] = []
    peaks: list[np.ndarray] = []
    seen = np.empty((0, 2))  # both, as one array

    def add(p, to):
        nonlocal seen
        p = (p + 0.5) / scale - 0.5  # to full-resolution pixels
        if far_from_all(p, seen, merge_px * unit):
            to.append(p)
            seen = np.vstack([seen, p])

    for dark, stats, cents in levels.regions:
        for i in range(1, len(stats)):
            if min_area_px / 4 <= stats[i, cv2.CC_STAT_AREA] <= max_area_px / 4:
                add(cents[i], centroids)
        if max_peaks:
            dist = cv2.distanceTransform(dark, cv2.DIST_L2, 3)
            v, u = np.nonzero((dist >= min_radius_px / 2) & (dist >= cv2.dilate(dist, peak_kernel)))
            for k in np.argsort(-dist[v, u])[:max_peaks]:
                add(np.array([u[k], v[k]], float), peaks)
    return centroids, peaks


def far_from_all(p: np.ndarray, points, limit: float) -> bool:
    """``all(np.linalg.norm(p - q) > limit for q in points)``, to the same answer, with the
    distances taken all at once (the one-by-one loop was most of the position hypotheses'
    time); a distance within a hair of ``limit`` is taken one by one as that loop did."""
    if not len(points):
        return True
    points = np.asarray(points, float)
    d = np.sqrt(((points - p) ** 2).sum(axis=1))
    hair = ~(np.abs(d - limit) > 1e-9 * max(1.0, abs(limit)))  # (and NaN)
    if np.any(d[~hair] <= limit):
        return False
    return all(np.linalg.norm(p - q) > limit for q, near in zip(points, hair) if near)


def position_hypotheses(views, points, max_miss_mm: float = 20.0, merge_mm: float = 8.0) -> list[np.ndarray]:
    """3D points where the rays through an image point in each of two views (nearly) meet,
    closest pairs first, merged within ``merge_mm``. ``points`` holds a list of pixel
    points per view."""
    if not len(points[0]) or not len(points[1]):
        return []
    (o1, d1), (o2, d2) = (view.ray(np.asarray(p, float)) for view, p in zip(views, points))
    # every pair at once: the closest points of rays o1 + s d1[i] and o2 + u d2[j]
    b = d1 @ d2.T
    w = o1 - o2
    e1, e2 = d1 @ w, d2 @ w
    denom = np.maximum(1.0 - b * b, 1e-12)
    s_ = (b * e2[None, :] - e1[:, None]) / denom
    u_ = (e2[None, :] - b * e1[:, None]) / denom
    p1 = o1 + s_[..., None] * d1[:, None, :]
    p2 = o2 + u_[..., None] * d2[None, :, :]
    miss = np.linalg.norm(p1 - p2, axis=-1).ravel()
    mid = ((p1 + p2) / 2.0).reshape(-1, 3)
    out: list[np.ndarray] = []
    kept = np.empty((len(mid), 3))  # out, as one array
    for k in np.argsort(miss):
        if miss[k] > max_miss_mm:
            break
        if far_from_all(mid[k], kept[:len(out)], merge_mm):
            kept[len(out)] = mid[k]
            out.append(mid[k])
    return out
