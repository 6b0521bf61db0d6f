"""Outline point files: ordered pixel points ``u,v`` one per line, optional header."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fluorogui.io.errors import InputError
from fluorogui.io.files import atomic_write_text, read_input_bytes

MAX_OUTLINE_BYTES = 50_000_000


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


def write_outline_csv(path, points) -> None:
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    body = "u,v\n" + "".join(f"{u:.4f},{v:.4f}\n" for u, v in points)
    atomic_write_text(path, body)
