"""CSV tables of poses: ``frame,component,x,y,z,alpha,beta,gamma`` (mm, degrees), one
pose per line, a header line first (the reference poses of validations).

Read through the common opening (``read_input_bytes``) and checked row by row against
``schema.ReferencePoseRow``: a missing column, a ragged row, a binary file or a value
that is not a finite number is one InputError naming the file and the line."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from fluorogui.io.errors import InputError, read_input_bytes
from fluorogui.io.schema import REFERENCE_COLUMNS, ReferencePoseRow, describe

MAX_TABLE_BYTES = 200_000_000


def read_text_table(path, what: str = "CSV file") -> str:
    """The text of a CSV file; binary files are refused."""
    raw = read_input_bytes(path, what, MAX_TABLE_BYTES)
    if b"\x00" in raw[:65536]:
        raise InputError(path, f"binary file, not a text {what}")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(path, f"not a text {what} (not UTF-8)") from None


def read_reference_poses(path, component: str | None = None) -> list[tuple[str, str, np.ndarray]]:
    """(frame, component, pose) of every line, or of ``component``'s lines only."""
    path = Path(path)
    lines = read_text_table(path, "pose CSV").splitlines()
    rows = [(n, row) for n, row in enumerate(csv.reader(lines), start=1) if any(c.strip() for c in row)]
    if not rows:
        raise InputError(path, "the pose CSV is empty")
    header = [c.strip().lower() for c in rows[0][1]]
    missing = [c for c in REFERENCE_COLUMNS if c not in header]
    if missing:
        raise InputError(path, f"line 1: the header lacks the column{'s' if len(missing) > 1 else ''} "
                               f"{', '.join(missing)} (expected {','.join(REFERENCE_COLUMNS)})")
    poses = []
    for n, row in rows[1:]:
        if len(row) != len(header):
            raise InputError(path, f"line {n} has {len(row)} values; the header has {len(header)}")
        try:
            parsed = ReferencePoseRow.from_csv({k: v.strip() for k, v in zip(header, row)})
        except ValueError as exc:
            text = describe(exc) if isinstance(exc, ValidationError) else str(exc)
            raise InputError(path, f"line {n}: {text}") from None
        if component is None or parsed.component == component:
            poses.append((parsed.frame, parsed.component, np.array(parsed.pose)))
    return poses
