"""Outline point files: ordered pixel points ``u,v`` one per line, optional header.

An outline traces a component in an image, so its points lie in that image:
``check_outline_in_image`` refuses one whose points lie beyond the image by more than
``OUTLINE_MARGIN`` of its size (points a little outside are kept: an outline closed along
the edge of the field of view, a spline's overshoot)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fluorogui.io.errors import InputError
from fluorogui.io.files import atomic_write_text, read_input_bytes

MAX_OUTLINE_BYTES = 50_000_000
#: how far beyond its image an outline's points may lie, as a share of the image's size
OUTLINE_MARGIN = 0.1


def read_outline_csv(path) -> np.ndarray:
    """(K, 2) float pixel points. Blank lines and one leading non-numeric header are skipped."""
    path = Path(path)
    raw = read_input_bytes(path, "outline file", MAX_OUTLINE_BYTES)
    if b"\x00" in raw[:65536]:
        raise InputError(path, "outline is not a text file")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(path, "outline is not a text file") from None
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = [p for p in line.replace(";", ",").replace("\t", ",").replace(" ", ",").split(",") if p]
        try:
            values = [float(p) for p in parts]
        except ValueError:
            if not rows and number <= 2:
                continue  # header
            raise InputError(path, f"line {number} is not two numbers u,v: {line[:40]!r}") from None
        if len(values) != 2:
            raise InputError(path, f"line {number} has {len(values)} values; expected u,v")
        rows.append(values)
    points = np.array(rows, dtype=float).reshape(-1, 2)
    if not np.all(np.isfinite(points)):
        raise InputError(path, "outline contains NaN or infinite values")
    if points.size and np.abs(points).max() > 1e6:
        raise InputError(path, "outline has points more than 10^6 pixels away")
    return points


def check_outline_in_image(points, image_size, path, view_name: str = "") -> None:
    """Refuse (InputError naming ``path``) outline points (pixels) farther outside an image
    of ``image_size`` (width, height) than ``OUTLINE_MARGIN`` of its size: an outline of
    another image, or of other units."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if not len(points):
        return
    width, height = image_size
    margin = OUTLINE_MARGIN * np.array([width, height], dtype=float)
    low, high = -0.5 - margin, np.array([width, height], dtype=float) - 0.5 + margin
    beyond = np.maximum(low - points, points - high).max(axis=1)
    worst = int(np.argmax(beyond))
    if beyond[worst] > 0:
        u, v = points[worst]
        where = f" of {view_name}" if view_name else ""
        raise InputError(path, f"outline point {worst + 1} ({u:.6g}, {v:.6g}) px lies outside the {width}x{height} px "
                               f"image{where} (by more than {OUTLINE_MARGIN:.0%} of its size): an outline of another "
                               "image?")


def write_outline_csv(path, points) -> None:
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    body = "u,v\n" + "".join(f"{u:.4f},{v:.4f}\n" for u, v in points)
    atomic_write_text(path, body)
