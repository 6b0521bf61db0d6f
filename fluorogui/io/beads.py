"""Bead-phantom files: a CSV of bead centres ``x,y,z`` in mm, the first bead the larger marker.

A header line (``x,y,z``) and an optional leading ``label`` / ``id`` column are accepted;
blank lines and lines starting with ``#`` are skipped.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from fluorogui.io.errors import InputError, describe_os_error


def read_phantom_csv(path) -> np.ndarray:
    """Bead centres (N, 3) in mm; InputError naming the file and line on a bad row."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except IsADirectoryError:
        raise InputError(path, "is a folder, not a CSV file") from None
    except UnicodeDecodeError:
        raise InputError(path, "not a text CSV file") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the file: {describe_os_error(exc)}") from None
    rows = []
    for number, row in enumerate(csv.reader(text.splitlines()), start=1):
        cells = [c.strip() for c in row if c.strip()]
        if not cells or cells[0].startswith("#"):
            continue
        if len(cells) == 4:
            cells = cells[1:]  # a label column
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if not rows:
                continue  # the header
            raise InputError(path, f"line {number}: non-numeric bead coordinate in {','.join(cells)!r}") from None
        if len(values) != 3:
            raise InputError(path, f"line {number} has {len(values)} numbers; a bead needs x,y,z (mm)")
        if not all(math.isfinite(v) for v in values):
            raise InputError(path, f"line {number}: NaN or infinite coordinate")
        rows.append(values)
    if not rows:
        raise InputError(path, "lists no beads (expected lines x,y,z in mm)")
    return np.array(rows, dtype=float)
