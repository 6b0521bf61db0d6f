"""Developer tool: intensity profiles along the outline normals of the tibial tray on the real
biplane data, a measure of its edges that shares no code with the matcher or the region fit.

At each frame's pose (default: the tray rows of ``tests/data/biplane_reference_poses.csv``) the
tray's projected region (``fluorogui.reference.region_fit.coverage``, 3 x 3 samples a pixel)
gives its outline; every 4th outline point is moved along its outward normal to where the
coverage is 1/2, and the image is sampled along that normal from 15 px inside to 45 px outside.
Points are sorted by where they lie on the tray (the nearest projected vertex's model z and
the normal's direction against the tray's projected z axis): the plate's ``top`` (facing the
joint), its ``rim`` (ends), its ``under``\\ side, the ``keel``'s sides and the stem's ``tip``.
Profiles crossing the femoral component (its region at its pose, dilated 4 px), the field of
view's edge or the tray again are left out.

Printed per view and class, medians over the profiles:

* the shape of the background: ``(I(d) - I(-8)) / (I(30) - I(-8))`` at distances ``d`` (px,
  outward), 0 on the metal and 1 at 30 px out. Bone and cement next to the metal show as a
  level that keeps rising 10-20 px out (``under``, ``keel``); a clean step (``top``) is flat
  after the blur;
* the edge's offset (px, outward) from the outline at the pose, two ways: where the profile
  crosses the half-way level between the metal (``d`` = -6 .. -4) and the near background
  (``d`` = 3 .. 5), and where it rises fastest (what an edge detector marks). With ``top``
  and ``under`` together they say whether the image's plate band is thinner than the
  mesh's at that pose; on the model's images (``--model``) what the blur and the
  background alone make of an exact mesh;
* the edge's blur: the median sigma (px) of an error function fitted to each profile
  across its edge (on ``top``, a clean step, the real images' blur: ``REAL_BLUR_PX``).

``--model`` prints the same for X-ray model images of the same poses (``fluorogui.reference.xray``
with the real images' blur, soft tissue along the tray, and the bone and cement zone of
``fluorogui.reference.zone``: what its parameters were matched to), where the pose is the truth.

Usage: .venv/bin/python tools/edge_profiles.py [--frames 0 50 100] [--poses CSV] [--model]
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fluorogui.io.calibration import load_view  # noqa: E402
from fluorogui.io.images import read_image  # noqa: E402
from fluorogui.io.meshes.read import load_mesh  # noqa: E402
from fluorogui.reference.region_fit import EdgeMesh, coverage, field_of_view, project, rotation  # noqa: E402

POSE_KEYS = ("x", "y", "z", "alpha", "beta", "gamma")
DISTANCES = np.arange(-15.0, 45.01, 0.5)
SHOWN = (-2, 0, 1, 2, 3, 4, 6, 8, 10, 12, 15, 18, 22, 26)
CLASSES = ("top", "rim", "under", "keel", "tip")


def _world(mesh: EdgeMesh, pose) -> np.ndarray:
    return mesh.vertices @ rotation(*pose[3:]).T + pose[:3]


def _region(view, mesh: EdgeMesh, pose, dilate_px: int) -> np.ndarray:
    w, h = view.image_size
    region = (coverage(view, _world(mesh, pose), mesh, (0, 0, w, h), s=1) > 0).astype(np.uint8)
    return cv2.dilate(region, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * dilate_px + 1,) * 2)).astype(bool)


def outline_profiles(image, view, mesh: EdgeMesh, pose, masked=None, step: int = 4):
    """(profiles (N, len(DISTANCES)), class per profile) of the tray at ``pose`` in one view."""
    world = _world(mesh, pose)
    uv = project(view, world)
    w, h = view.image_size
    u0, v0 = int(max(uv[:, 0].min() - 60, 0)), int(max(uv[:, 1].min() - 60, 0))
    u1, v1 = int(min(uv[:, 0].max() + 60, w)), int(min(uv[:, 1].max() + 60, h))
    cover = coverage(view, world, mesh, (u0, v0, u1, v1), s=3).astype(np.float32)
    inside = (cover >= 0.5).astype(np.uint8)
    contours, _ = cv2.findContours(inside, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(contours, key=len)[:, 0, :].astype(float)
    k = 5  # smoothed outline, normals from it
    ring = np.vstack([c[-k:], c, c[:k]])
    smooth = np.array([ring[i:i + 2 * k + 1].mean(0) for i in range(len(c))])
    t = np.roll(smooth, -2, 0) - np.roll(smooth, 2, 0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    n = np.column_stack([t[:, 1], -t[:, 0]])
    probe = np.clip(np.round(smooth + 3 * n).astype(int), 0, [inside.shape[1] - 1, inside.shape[0] - 1])
    if inside[probe[:, 1], probe[:, 0]].mean() > 0.5:
        n = -n  # outward
    smooth, n = smooth[::step], n[::step]
    # where the coverage is 1/2 along each normal
    dd = np.arange(-3.0, 3.01, 0.05)
    along = cv2.remap(cover, (smooth[:, None, 0] + dd * n[:, None, 0]).astype(np.float32),
                      (smooth[:, None, 1] + dd * n[:, None, 1]).astype(np.float32), cv2.INTER_LINEAR)
    half = np.array([np.interp(0.5, row[::-1], dd[::-1]) if row[0] > 0.5 > row[-1] else np.nan for row in along])
    base = smooth + np.nan_to_num(half)[:, None] * n + (u0, v0)
    dist, nearest = cKDTree(uv).query(base)
    model_z = mesh.vertices[nearest, 2]
    R = rotation(*pose[3:])
    centre = world.mean(0)
    z_img = np.diff(project(view, np.vstack([centre, centre + R[:, 2]])), axis=0)[0]
    facing = n @ (z_img / np.linalg.norm(z_img))
    P = base[:, None, :] + DISTANCES[None, :, None] * n[:, None, :]
    profiles = cv2.remap(image.astype(np.float32), P[..., 0].astype(np.float32), P[..., 1].astype(np.float32),
                         cv2.INTER_LINEAR)
    iu, iv = np.clip(np.round(P[..., 0]).astype(int), 0, w - 1), np.clip(np.round(P[..., 1]).astype(int), 0, h - 1)
    tray = np.zeros((h, w), dtype=bool)
    tray[v0:v1, u0:u1] = inside > 0
    bad = tray[iv, iu] & (DISTANCES[None] > 2)
    if masked is not None:
        bad |= masked[iv, iu]
    keep = np.isfinite(half) & ~bad.any(1) & (dist < 3)
    low = model_z.min()
    cls = np.where(model_z < low + 6, "tip", np.where((model_z < -2.5) & (model_z > -7) & (facing < -0.5), "under",
                   np.where(model_z <= -7, "keel", np.where(facing > 0.5, "top", "rim"))))
    return profiles[keep], cls[keep]


def shape(p: np.ndarray) -> np.ndarray:
    """Median of (I(d) - I(-8)) / (I(30) - I(-8)) over the profiles."""
    i0, i1 = np.searchsorted(DISTANCES, -8.0), np.searchsorted(DISTANCES, 30.0)
    return np.median((p - p[:, [i0]]) / np.maximum(p[:, [i1]] - p[:, [i0]], 1e-3), axis=0)


def edge_offsets(p: np.ndarray) -> np.ndarray:
    """Per profile, where (px, outward) it crosses half-way between the metal and the near background."""
    metal = p[:, (DISTANCES >= -6) & (DISTANCES <= -4)].mean(1)
    near = p[:, (DISTANCES >= 3) & (DISTANCES <= 5)].mean(1)
    out = np.full(len(p), np.nan)
    window = (DISTANCES >= -4) & (DISTANCES <= 3)
    d = DISTANCES[window]
    for i, row in enumerate(p[:, window]):
        level = (metal[i] + near[i]) / 2
        above = np.nonzero(row >= level)[0]
        if near[i] - metal[i] > 0.01 and len(above) and above[0] > 0:
            j = above[0]
            out[i] = d[j - 1] + (level - row[j - 1]) / (row[j] - row[j - 1]) * (d[j] - d[j - 1])
    return out


def steepest(p: np.ndarray) -> np.ndarray:
    """Per profile, where (px, outward) it rises fastest within 4 px of the outline (what an
    edge detector marks), to a fraction of a pixel by a parabola through the peak."""
    window = (DISTANCES >= -4) & (DISTANCES <= 4)
    d = DISTANCES[window]
    slope = np.gradient(p[:, window], d, axis=1)
    k = np.clip(np.argmax(slope, axis=1), 1, len(d) - 2)
    rows = np.arange(len(p))
    a, b, c = slope[rows, k - 1], slope[rows, k], slope[rows, k + 1]
    shift = np.where(np.abs(a - 2 * b + c) > 1e-9, 0.5 * (a - c) / np.where(np.abs(a - 2 * b + c) > 1e-9,
                                                                                 a - 2 * b + c, 1.0), 0.0)
    return d[k] + np.clip(shift, -1, 1) * (d[1] - d[0])


def blur_sigma(p: np.ndarray) -> float:
    """Median over the profiles of the sigma (px) of an error function fitted to each across
    its edge (-6 .. 6 px): the edge's blur, free of how the profiles line up."""
    from scipy.optimize import curve_fit
    from scipy.special import erf

    def step(d, low, rise, at, sigma):
        return low + rise * 0.5 * (1.0 + erf((d - at) / (np.sqrt(2.0) * sigma)))

    near = (DISTANCES >= -6) & (DISTANCES <= 6)
    sigmas = []
    for row in p[:, near]:
        try:
            fit, _ = curve_fit(step, DISTANCES[near], row, p0=[row[0], row[-1] - row[0], 0.0, 1.2], maxfev=2000)
        except RuntimeError:
            continue
        if fit[1] > 0.02 and 0.2 < abs(fit[3]) < 5.0:
            sigmas.append(abs(fit[3]))
    return float(np.median(sigmas)) if sigmas else float("nan")


def report(title: str, acc: dict) -> None:
    idx = [int(np.argmin(np.abs(DISTANCES - d))) for d in SHOWN]
    print(title)
    print(f"{'view':>4} {'class':6} {'n':>5}  half-way (IQR)      steepest  blur  "
          + " ".join(f"{d:>5}" for d in SHOWN))
    for (view, cls), parts in sorted(acc.items(), key=lambda kv: (kv[0][0], CLASSES.index(kv[0][1]))):
        p = np.vstack(parts)
        q1, med, q3 = np.nanpercentile(edge_offsets(p), [25, 50, 75])
        print(f"{view + 1:4d} {cls:6} {len(p):5d}  {med:+.2f} ({q1:+.2f} {q3:+.2f})  "
              f"{np.median(steepest(p)):+.2f}     {blur_sigma(p):.2f}  "
              + " ".join(f"{v:5.2f}" for v in shape(p)[idx]))


def model_images(views, meshes, pose, rng):
    from fluorogui.reference.xray import MU_METAL, MU_TISSUE, Body, Cylinder, XrayModel, xray_image
    from fluorogui.reference.zone import REAL_BLUR_PX, tray_zone

    M = np.eye(4)
    M[:3, :3], M[:3, 3] = rotation(*pose[3:]), pose[:3]
    world = _world(meshes["tibial"], pose)
    leg = Cylinder(tuple(world.mean(0)), tuple(M[:3, 2]), 50.0, MU_TISSUE)
    model = XrayModel(background=[leg], zones=[tray_zone(meshes["tibial"].vertices, meshes["tibial"].faces, M)],
                      detector_blur_px=REAL_BLUR_PX)
    return [xray_image(v, [Body(world, meshes["tibial"].faces, MU_METAL)], model, rng) for v in views]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "biplane-tka")
    ap.add_argument("--poses", type=Path, default=ROOT / "tests" / "data" / "biplane_reference_poses.csv")
    ap.add_argument("--frames", type=int, nargs="+", help="default: every frame with a tray pose")
    ap.add_argument("--model", action="store_true", help="also X-ray model images of the same poses")
    args = ap.parse_args(argv)
    views = [load_view(args.data / f"calibration/cam{k}_mayacam2.txt") for k in (1, 2)]
    with open(args.data / "pairs.csv", newline="") as fh:
        pairs = {int(r["frame"]): (r["cam1"], r["cam2"]) for r in csv.DictReader(fh)}
    with open(args.poses, newline="") as fh:
        poses = {(int(r["frame"]), r["component"]): np.array([float(r[k]) for k in POSE_KEYS])
                 for r in csv.DictReader(fh)}
    meshes = {c: EdgeMesh.from_arrays(*load_mesh(args.data / f"models/{c}_component.stl"))
              for c in ("femoral", "tibial")}
    frames = args.frames or sorted(f for f, c in poses if c == "tibial")
    rng = np.random.default_rng(0)
    real, model = {}, {}
    for frame in frames:
        pose = poses[frame, "tibial"]
        images = [read_image(args.data / p) for p in pairs[frame]]
        for k, (view, image) in enumerate(zip(views, images)):
            masked = ~field_of_view(image)
            if (frame, "femoral") in poses:
                masked |= _region(view, meshes["femoral"], poses[frame, "femoral"], 4)
            p, cls = outline_profiles(image, view, meshes["tibial"], pose, masked)
            for c in np.unique(cls):
                real.setdefault((k, str(c)), []).append(p[cls == c])
        if args.model:
            for k, (view, image) in enumerate(zip(views, model_images(views, meshes, pose, rng))):
                p, cls = outline_profiles(image, view, meshes["tibial"], pose, ~field_of_view(image))
                for c in np.unique(cls):
                    model.setdefault((k, str(c)), []).append(p[cls == c])
    report(f"real images, {len(frames)} frames, poses from {args.poses.name}: edge offset from the outline at "
           "the pose, then (I(d) - I(-8)) / (I(30) - I(-8)) at d px outward", real)
    if args.model:
        report("X-ray model images at the same poses (the truth)", model)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
