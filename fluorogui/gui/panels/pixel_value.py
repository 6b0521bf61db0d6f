"""The raw value of an image file at a pixel, for the status bar.

The workflow works on images scaled to [0, 1] (``fluorogui.io.images.read_image``); a user
reading a pixel wants the number in the file (60 in a 16-bit TIFF, not 0.0009). The raw
pixels of the image under the cursor are read once, on the first hover, and kept for the
few images on screen. Qt-free.
"""
from __future__ import annotations

from collections import OrderedDict
from pathlib import Path

import numpy as np

from fluorogui.io.images import has_dicom_preamble

KEEP_IMAGES = 4


def read_raw_pixels(path) -> np.ndarray | None:
    """The stored pixel values of an image file (any dtype, grey or colour), None when
    the file cannot be read this way (the caller then shows the scaled value)."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix in (".tif", ".tiff"):
            import tifffile

            return np.asarray(tifffile.imread(path, key=0))
        if suffix in (".dcm", ".dicom") or has_dicom_preamble(path):
            import pydicom

            dataset = pydicom.dcmread(path)
            pixels = dataset.pixel_array.astype(np.float64)
            slope = float(getattr(dataset, "RescaleSlope", 1.0) or 1.0)
            intercept = float(getattr(dataset, "RescaleIntercept", 0.0) or 0.0)
            return pixels * slope + intercept
        import cv2

        pixels = cv2.imdecode(np.fromfile(path, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
        if pixels is not None and pixels.ndim == 3 and pixels.shape[2] >= 3:
            pixels = pixels[:, :, [2, 1, 0, *range(3, pixels.shape[2])]]  # BGR(A) -> RGB(A)
        return pixels
    except Exception:  # noqa: BLE001 - an unreadable file falls back to the scaled value
        return None


def format_value(value) -> str:
    """A pixel value as text: integers as they are, floats to 4 significant digits,
    colour as r,g,b."""
    array = np.asarray(value)
    if array.ndim > 0:
        return ",".join(format_value(v) for v in array.ravel()[:4])
    if np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.bool_):
        return str(int(array))
    number = float(array)
    if not np.isfinite(number):
        return "–"
    return str(int(number)) if number.is_integer() else f"{number:.4g}"


class RawPixels:
    """Raw pixel lookup by file, reading each file once (the last few are kept)."""

    def __init__(self, keep: int = KEEP_IMAGES):
        self.keep = keep
        self._cache: OrderedDict[Path, np.ndarray | None] = OrderedDict()

    def pixels(self, path) -> np.ndarray | None:
        path = Path(path)
        if path in self._cache:
            self._cache.move_to_end(path)
            return self._cache[path]
        pixels = read_raw_pixels(path)
        self._cache[path] = pixels
        while len(self._cache) > self.keep:
            self._cache.popitem(last=False)
        return pixels

    def value_at(self, path, u: float, v: float, shape: tuple[int, int] | None = None):
        """The stored value at the pixel holding (u, v) (pixel centres at integers), None
        outside the image, unreadable, or when its size is not ``shape`` (rows, columns)."""
        pixels = self.pixels(path)
        if pixels is None or pixels.ndim < 2:
            return None
        if shape is not None and tuple(pixels.shape[:2]) != tuple(shape):
            return None
        col, row = int(np.floor(u + 0.5)), int(np.floor(v + 0.5))
        if 0 <= row < pixels.shape[0] and 0 <= col < pixels.shape[1]:
            return pixels[row, col]
        return None
