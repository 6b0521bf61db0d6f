"""The orientation grid *find implants* starts from, and the intensifier's field of view."""
import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from fluorogui.core.outlines.field import field_of_view, intensifier_disc, to_unit_float
from fluorogui.core.search.orientation import orientation_grid


def test_orientation_grid_is_spread_over_so3():
    R = orientation_grid(500)
    assert R.shape == (500, 3, 3)
    assert np.allclose(np.einsum("nij,nkj->nik", R, R), np.eye(3), atol=1e-9)
    # every random rotation is within ~25 degrees of a grid rotation
    rng = np.random.default_rng(1)
    probes = Rotation.random(50, random_state=rng).as_matrix()
    cos = (np.einsum("pij,nij->pn", probes, R) - 1) / 2
    nearest = np.degrees(np.arccos(np.clip(cos.max(1), -1, 1)))
    assert nearest.max() < 30.0  # measured 22.3 deg


def _disc_image(size, radius, frame_grey=0.0, noise=0.0, seed=0):
    yy, xx = np.mgrid[0:size, 0:size]
    c = (size - 1) / 2
    disc = (xx - c) ** 2 + (yy - c) ** 2 < radius ** 2
    img = np.where(disc, 200.0, frame_grey) + np.random.default_rng(seed).normal(0, noise, (size, size))
    return img, disc


def test_disc_with_a_frame_that_is_not_black():
    # the frame of some intensifier images (and of the generated sequences) is dark grey
    # and noisy, darker than the field but not than a quarter of the metal's grey
    img, _ = _disc_image(512, 230, frame_grey=16.0, noise=5.0)
    yy, xx = np.mgrid[0:512, 0:512]
    cv2.ellipse(img, (256, 256), (40, 30), 0, 0, 360, 50, -1)  # metal, darker than the frame's quarter
    fov = intensifier_disc(np.clip(img, 0, 255).astype(np.uint8), margin_px=10)
    assert fov[256, 256] and not fov[5, 5] and not fov[256, 20]
    assert abs(fov.sum() - np.pi * 220 ** 2) < 0.03 * np.pi * 220 ** 2


def test_disc_keeps_dark_components_inside_it():
    img, _ = _disc_image(512, 240)
    img = cv2.GaussianBlur(img.astype(np.uint8), (0, 0), 4)
    cv2.ellipse(img, (200, 180), (60, 40), 0, 0, 360, 40, -1)  # a component darker than the frame's quarter
    fov = intensifier_disc(img, margin_px=10)
    assert not fov[0, 0] and fov[256, 256] and fov[180, 200]


def test_field_of_view_at_full_resolution_shrinks_by_its_margin():
    # a 1024-pixel image: the disc is found at half resolution, the margin is in half-size pixels
    img, disc = _disc_image(1024, 480)
    fov = field_of_view(img.astype(np.float32) / 255.0, margin_px=15)
    assert fov.shape == (1024, 1024) and fov.dtype == bool
    radius = np.sqrt(fov.sum() / np.pi)
    assert abs(radius - (480 - 2 * 15)) < 3.0  # 15 px at half resolution is 30 px here
    assert not (fov & ~disc).any()


def test_unit_float_images_are_the_copy_they_were():
    """Without the copy of an image that already is float32 in [0, 1], the same numbers."""
    img, _ = _disc_image(64, 20, noise=3.0)
    for image in (img, img.astype(np.float32), img.astype(np.uint8), np.clip(img, 0, 255).astype(np.float32) / 255.0,
                  np.clip(img, 0, 255).astype(np.uint16), np.dstack([img] * 3).astype(np.uint8)):
        plain = np.asarray(image).astype(np.float32)
        if plain.ndim == 3:
            plain = cv2.cvtColor(plain, cv2.COLOR_BGR2GRAY)
        lo, hi = float(plain.min()), float(plain.max())
        if lo < 0.0 or hi > 1.0:
            plain = (plain - lo) / max(hi - lo, 1e-12)
        got = to_unit_float(image)
        assert got.dtype == np.float32 and np.array_equal(got, plain)
