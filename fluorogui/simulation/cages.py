"""Calibration cages and their X-ray images, for testing the bead calibration on phantoms
that are not the one shipped with the package.

- ``two_plate_grid_cage``: a common lab design, steel beads on two parallel plates, each
  plate a regular grid, one larger marker bead (the first). Seen obliquely the two grids
  overlap in the image, which makes correspondences by affine guesses ambiguous.
- ``helix_cage``: beads along a helix on a cylinder (a screw symmetry that only the
  marker breaks).
- ``irregular_cage``: beads scattered in a box, kept apart.

``oblique_camera`` places a pinhole ``x_cam = R X + t``, ``uv = K x_cam / z`` (pixels,
rows down) at a given tilt from the cage's z axis (``TWO_VIEWS``: the two views the tests
and ``benchmarks/bench_cages.py`` calibrate); ``render_cage`` draws the beads as
X-ray attenuation: each pixel is the mean over sub-pixel rays of ``exp(-mu * chord)``,
the chord being the ray's path through every bead it crosses (so the silhouettes are
the exact perspective ellipses and overlapping beads darken together), times a smooth
vignetting field, then blurred and given quantum-like noise. The projection is written
out here, independent of the calibration code and of ``View``. ``write_cage_scene`` writes
the images (16-bit TIFF) and the phantom file that ``fluorogui calibrate geometry`` reads.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fluorogui.core.projection.geometry import View
from fluorogui.io.images import write_image

# (tilt from the plates' normal, azimuth, roll) in degrees of the two views calibrated by the
# tests and the benchmark: both looking up through the cage, 100 degrees apart in azimuth
TWO_VIEWS = ((15.0, 20.0, 5.0), (30.0, 120.0, -10.0))


@dataclass(frozen=True)
class Cage:
    """Bead centres (N, 3) mm, the first one the marker, and each bead's diameter (mm)."""

    name: str
    beads: np.ndarray
    diameters: np.ndarray

    def csv_text(self) -> str:
        """The phantom file the calibration reads: ``x,y,z`` per bead, marker first."""
        return "x,y,z\n" + "".join(f"{x!r},{y!r},{z!r}\n" for x, y, z in self.beads.astype(float).tolist())


def two_plate_grid_cage(*, plate_gap: float = 120.0, spacing: float = 30.0, grid_a=(4, 4), grid_b=(4, 3),
                        bead_mm: float = 2.5, marker_mm: float = 5.0, marker_node=(1, 3)) -> Cage:
    """Plate A at z = +gap/2 with a ``grid_a`` (columns, rows) grid, plate B at z = -gap/2
    with ``grid_b``, both centred on the z axis with the same ``spacing``. The marker takes
    the place of plate A's node ``marker_node`` (column, row); the default (4x4 + 4x3 with
    the marker off both diagonals) is 28 beads and has no symmetry that keeps the marker."""
    def plate(grid, z):
        cols, rows = grid
        x = (np.arange(cols) - (cols - 1) / 2) * spacing
        y = (np.arange(rows) - (rows - 1) / 2) * spacing
        xx, yy = np.meshgrid(x, y, indexing="ij")
        return np.column_stack([xx.ravel(), yy.ravel(), np.full(xx.size, z)])

    a, b = plate(grid_a, plate_gap / 2), plate(grid_b, -plate_gap / 2)
    marker = marker_node[0] * grid_a[1] + marker_node[1]
    beads = np.concatenate([a[[marker]], np.delete(a, marker, axis=0), b])
    diameters = np.full(len(beads), bead_mm)
    diameters[0] = marker_mm
    return Cage("two-plate grid", beads, diameters)


def helix_cage(*, n: int = 24, radius: float = 50.0, height: float = 120.0, turns: float = 2.0,
               bead_mm: float = 2.5, marker_mm: float = 5.0) -> Cage:
    """``n`` beads evenly along a helix of ``turns`` turns about the z axis; the marker is
    the bottom one."""
    s = np.linspace(0.0, 1.0, n)
    phi = 2 * np.pi * turns * s
    beads = np.column_stack([radius * np.cos(phi), radius * np.sin(phi), height * (s - 0.5)])
    diameters = np.full(n, bead_mm)
    diameters[0] = marker_mm
    return Cage("helix", beads, diameters)


def irregular_cage(*, n: int = 26, box: float = 120.0, min_gap: float = 15.0, bead_mm: float = 2.5,
                   marker_mm: float = 5.0, seed: int = 3) -> Cage:
    """``n`` beads drawn uniformly in a cube of side ``box``, each at least ``min_gap`` from
    the others; the marker is the first."""
    rng = np.random.default_rng(seed)
    beads = []
    while len(beads) < n:
        p = rng.uniform(-box / 2, box / 2, 3)
        if all(np.linalg.norm(p - q) >= min_gap for q in beads):
            beads.append(p)
    diameters = np.full(n, bead_mm)
    diameters[0] = marker_mm
    return Cage("irregular", np.array(beads), diameters)


@dataclass(frozen=True)
class Camera:
    """A pinhole ``x_cam = R X + t``, ``uv = K x_cam / z`` for an image ``size`` (w, h)."""

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    size: tuple[int, int]
    pitch: float

    @property
    def source(self) -> np.ndarray:
        return -self.R.T @ self.t

    @property
    def source_to_intensifier(self) -> float:
        return float(self.K[0, 0] * self.pitch)

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (N, 2) and depths (N,) of world points (N, 3)."""
        cam = np.asarray(points, dtype=float) @ self.R.T + self.t
        h = cam @ self.K.T
        return h[:, :2] / h[:, 2:], cam[:, 2]

    def view(self, name: str = "") -> View:
        return View.from_pinhole(self.K, self.R, self.t, self.size, pitch=self.pitch, name=name)


def oblique_camera(tilt_deg: float, *, azimuth_deg: float = 0.0, roll_deg: float = 0.0,
                   source_to_cage: float = 750.0, source_to_intensifier: float = 1100.0,
                   size: tuple[int, int] = (1024, 1024), pitch: float = 0.3,
                   principal_offset_px=(6.0, -4.0), aim=(0.0, 0.0, 0.0)) -> Camera:
    """A camera ``source_to_cage`` mm from the point ``aim``, its principal ray at
    ``tilt_deg`` from the cage's -z axis (the source below, looking up through both plates)
    turned by ``azimuth_deg`` about z, the image rolled by ``roll_deg``."""
    tilt, azimuth, roll = np.radians([tilt_deg, azimuth_deg, roll_deg])
    towards = np.array([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    source = np.asarray(aim, dtype=float) - source_to_cage * towards
    helper = np.array([0.0, 0.0, 1.0]) if abs(towards[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e_u = np.cross(helper, towards)
    e_u /= np.linalg.norm(e_u)
    e_v = np.cross(towards, e_u)
    c, s = np.cos(roll), np.sin(roll)
    e_u, e_v = c * e_u + s * e_v, -s * e_u + c * e_v
    R = np.vstack([e_u, e_v, towards])  # right-handed: e_u x e_v = towards
    f = source_to_intensifier / pitch
    w, h = size
    K = np.array([[f, 0, (w - 1) / 2 + principal_offset_px[0]], [0, f, (h - 1) / 2 + principal_offset_px[1]],
                  [0, 0, 1.0]])
    return Camera(K, R, -R @ source, (int(w), int(h)), float(pitch))


def render_cage(cage: Cage, camera: Camera, *, mu_per_mm: float = 0.8, field: float = 0.85, vignetting: float = 0.12,
                blur_px: float = 0.7, noise: float = 0.012, seed: int = 0, supersample: int = 4) -> np.ndarray:
    """The cage's X-ray image (H, W) float32 in [0, 1]: dark beads on a bright field.

    ``noise`` is the SD of the noise on the bright field; it scales with the square root
    of the signal (photon noise)."""
    w, h = camera.size
    Kinv = np.linalg.inv(camera.K)
    centres_cam = cage.beads @ camera.R.T + camera.t
    uv, depth = camera.project(cage.beads)
    radii = cage.diameters / 2
    boxes = []
    for (u, v), z, r in zip(uv, depth, radii):
        reach = 1.2 * r * camera.K[0, 0] / z + 3  # the ellipse's half-axes stay within this
        box = (max(int(np.floor(v - reach)), 0), min(int(np.ceil(v + reach)) + 1, h),
               max(int(np.floor(u - reach)), 0), min(int(np.ceil(u + reach)) + 1, w))
        boxes.append(box if box[0] < box[1] and box[2] < box[3] else None)
    drawn = [b for b in boxes if b is not None]
    transmission = np.ones((h, w))
    if drawn:
        top, left = min(b[0] for b in drawn), min(b[2] for b in drawn)
        bottom, right = max(b[1] for b in drawn), max(b[3] for b in drawn)
        offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
        du, dv = (g.ravel() for g in np.meshgrid(offsets, offsets, indexing="xy"))
        path = np.zeros((bottom - top, right - left, du.size), dtype=np.float32)  # mm through steel per sample
        for centre, r, box in zip(centres_cam, radii, boxes):
            if box is None:
                continue
            v0, v1, u0, u1 = box
            vv, uu = np.mgrid[v0:v1, u0:u1].astype(float)
            rays = np.stack([uu[..., None] + du, vv[..., None] + dv, np.ones((*uu.shape, du.size))], axis=-1)
            rays = rays @ Kinv.T
            rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
            miss2 = centre @ centre - (rays @ centre) ** 2  # squared distance from the bead centre to the ray
            path[v0 - top:v1 - top, u0 - left:u1 - left] += 2 * np.sqrt(np.clip(r * r - miss2, 0.0, None))
        transmission[top:bottom, left:right] = np.exp(-mu_per_mm * path).mean(axis=-1)
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    rr = ((xx - (w - 1) / 2) ** 2 + (yy - (h - 1) / 2) ** 2) / (0.5 * max(w, h)) ** 2
    image = field * (1 - vignetting * rr) * transmission
    if blur_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur_px)
    rng = np.random.default_rng(seed)
    image = image + rng.normal(0.0, 1.0, image.shape) * noise * np.sqrt(np.clip(image / field, 0.0, None))
    return np.clip(image, 0.0, 1.0).astype(np.float32)


def cage_scene(cage: Cage, cameras, seed: int = 0, **render) -> list[tuple[Camera, np.ndarray]]:
    """Each camera with its rendered image (noise seeded per view from ``seed``)."""
    return [(cam, render_cage(cage, cam, seed=seed + k, **render)) for k, cam in enumerate(cameras)]


def two_view_cameras(**camera) -> list[Camera]:
    """The cameras of ``TWO_VIEWS`` (``oblique_camera``'s keywords otherwise)."""
    return [oblique_camera(tilt, azimuth_deg=azimuth, roll_deg=roll, **camera) for tilt, azimuth, roll in TWO_VIEWS]


def write_cage_scene(cage: Cage, cameras, folder, seed: int = 0, **render) -> tuple[list[Path], Path]:
    """Each camera's image as ``folder/view{k}.tif`` (16-bit) and the phantom file
    ``folder/phantom.csv``; returns the image paths and the phantom file's."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for k, (_, image) in enumerate(cage_scene(cage, cameras, seed=seed, **render)):
        paths.append(folder / f"view{k + 1}.tif")
        write_image(paths[-1], image, bits=16)
    phantom = folder / "phantom.csv"
    phantom.write_text(cage.csv_text())
    return paths, phantom
