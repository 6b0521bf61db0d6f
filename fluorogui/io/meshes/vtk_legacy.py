"""Read legacy VTK POLYDATA files (``.vtk``, versions up to 5.1, ASCII or BINARY) with numpy.

VTK's own legacy reader crashes (SIGSEGV / SIGABRT) on corrupt cell arrays, so polygon
files are parsed here and every count and index is checked before VTK sees the mesh.
Sections read: POINTS, VERTICES / LINES (skipped), POLYGONS, TRIANGLE_STRIPS (split into
triangles); reading stops at POINT_DATA / CELL_DATA. Cell arrays are either the old
``n size`` + ``k i j ...`` lists or 5.1's OFFSETS / CONNECTIVITY pairs.
"""
from __future__ import annotations

import numpy as np

_TYPES = {"float": "f4", "double": "f8", "int": "i4", "unsigned_int": "u4", "long": "i8", "unsigned_long": "u8",
          "vtktypeint64": "i8", "vtktypeint32": "i4", "short": "i2", "unsigned_short": "u2", "char": "i1",
          "unsigned_char": "u1"}
_CELLS = ("VERTICES", "LINES", "POLYGONS", "TRIANGLE_STRIPS")


class LegacyVtkError(ValueError):
    """What is wrong with the file, in words."""


class _Cursor:
    def __init__(self, data: bytes, binary: bool):
        self.data, self.at, self.binary = data, 0, binary

    def line(self) -> list[str]:
        """The next non-blank line's words (empty at the end of the file)."""
        while self.at < len(self.data):
            end = self.data.find(b"\n", self.at)
            end = len(self.data) if end < 0 else end
            words = self.data[self.at:end].decode("latin-1").split()
            self.at = end + 1
            if words:
                return words
        return []

    def values(self, count: int, type_name: str) -> np.ndarray:
        code = _TYPES.get(type_name.lower())
        if code is None:
            raise LegacyVtkError(f"unknown data type {type_name[:20]!r}")
        if self.binary:
            size = count * int(code[1])
            if self.at + size > len(self.data):
                raise LegacyVtkError("the file ends inside a data block (truncated)")
            array = np.frombuffer(self.data, dtype=">" + code, count=count, offset=self.at)
            self.at += size
            if self.data[self.at:self.at + 1] == b"\n":
                self.at += 1
            return array
        values: list[str] = []
        while len(values) < count:
            words = self.line()
            if not words:
                raise LegacyVtkError("the file ends inside a data block (truncated)")
            values.extend(words)
        if len(values) != count:
            raise LegacyVtkError(f"a data block holds {len(values)} values where {count} are expected")
        try:
            return np.array(values, dtype=np.float64 if code[0] == "f" else np.int64)
        except ValueError:
            raise LegacyVtkError("a data block holds something that is not a number") from None


def _count(word: str) -> int:
    if not word.isdigit():
        raise LegacyVtkError(f"the count {word[:20]!r} is not a whole number")
    return int(word)


def _cell_array(cursor: _Cursor, words: list[str], version: float) -> list[np.ndarray]:
    if len(words) != 3:
        raise LegacyVtkError(f"'{words[0]}' needs two counts")
    first, second = _count(words[1]), _count(words[2])
    if version >= 5.0:
        offsets_line = cursor.line()
        if offsets_line[:1] != ["OFFSETS"] or len(offsets_line) != 2:
            raise LegacyVtkError(f"'{words[0]}' lacks its OFFSETS")
        offsets = cursor.values(first, offsets_line[1]).astype(np.int64)
        connectivity_line = cursor.line()
        if connectivity_line[:1] != ["CONNECTIVITY"] or len(connectivity_line) != 2:
            raise LegacyVtkError(f"'{words[0]}' lacks its CONNECTIVITY")
        connectivity = cursor.values(second, connectivity_line[1]).astype(np.int64)
        if first == 0:
            return []
        if offsets[0] != 0 or offsets[-1] != second or np.any(np.diff(offsets) < 0):
            raise LegacyVtkError(f"the OFFSETS of '{words[0]}' do not fit its CONNECTIVITY")
        return np.split(connectivity, offsets[1:-1])
    flat = cursor.values(second, "int").astype(np.int64)
    cells, at = [], 0
    for _ in range(first):
        if at >= flat.size or flat[at] < 0 or at + 1 + flat[at] > flat.size:
            raise LegacyVtkError(f"the cell list of '{words[0]}' is inconsistent with its counts")
        cells.append(flat[at + 1:at + 1 + flat[at]])
        at += 1 + int(flat[at])
    return cells


def read_legacy_polydata(data: bytes) -> tuple[np.ndarray, list[np.ndarray]]:
    """Points (N, 3) and polygons (lists of point indices, all checked to be in range)."""
    cursor = _Cursor(data, binary=False)
    head = cursor.line()
    if head[:2] != ["#", "vtk"]:
        raise LegacyVtkError("not a legacy VTK file (no '# vtk DataFile' line)")
    try:
        version = float(head[-1])
    except ValueError:
        version = 4.2
    cursor.at = data.find(b"\n", data.find(b"\n") + 1) + 1  # skip the title line
    kind = cursor.line()
    if kind not in (["ASCII"], ["BINARY"]):
        raise LegacyVtkError("the third line must be ASCII or BINARY")
    cursor.binary = kind == ["BINARY"]
    if cursor.line() != ["DATASET", "POLYDATA"]:
        raise LegacyVtkError("only 'DATASET POLYDATA' files are read")
    points, polygons, in_metadata = None, [], False
    while True:
        words = cursor.line()
        if not words or words[0] in ("POINT_DATA", "CELL_DATA", "FIELD"):
            break
        if words[0] == "METADATA" or (in_metadata and words[0] not in ("POINTS",) + _CELLS):
            in_metadata = True  # information keys of 5.1 writers: skipped
            continue
        in_metadata = False
        if words[0] == "POINTS" and len(words) == 3:
            points = cursor.values(3 * _count(words[1]), words[2]).astype(np.float64).reshape(-1, 3)
        elif words[0] in _CELLS:
            cells = _cell_array(cursor, words, version)
            if words[0] == "POLYGONS":
                polygons.extend(cells)
            elif words[0] == "TRIANGLE_STRIPS":
                for strip in cells:
                    polygons.extend(strip[i:i + 3] for i in range(len(strip) - 2))
        else:
            raise LegacyVtkError(f"unexpected line starting {words[0][:20]!r}")
    if points is None:
        raise LegacyVtkError("the file has no POINTS")
    for cell in polygons:
        if cell.size < 3:
            raise LegacyVtkError("a polygon has fewer than 3 corners")
        if cell.min() < 0 or cell.max() >= len(points):
            raise LegacyVtkError(f"a polygon refers to a point beyond the {len(points)} the file has")
    return points, polygons
