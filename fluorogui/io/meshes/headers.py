"""Check what a mesh file's header claims before VTK allocates for it.

VTK's readers size their arrays from the header's counts: a 278-byte PLY that claims
billions of vertices made VTK ask for 25 GB and abort the process. ``check_mesh_header``
reads only the header and refuses counts the file cannot hold (every element needs a
least number of bytes, in text or binary) or that exceed ``MAX_POINTS`` / ``MAX_CELLS``.
Formats without counts (OBJ, ASCII STL) are read as a stream and need no check.
"""
from __future__ import annotations

import re
import struct
from pathlib import Path

MAX_POINTS = 20_000_000  # an implant model has some 10^4-10^5
MAX_CELLS = 40_000_000
_HEADER_BYTES = 65536
_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


class HeaderError(ValueError):
    """The header is malformed or claims more than the file holds; the message says what."""


def check_mesh_header(path: Path) -> None:
    """Raise HeaderError when the header of the mesh file at ``path`` is malformed or
    claims more points or cells than the file can hold."""
    size = path.stat().st_size
    with open(path, "rb") as handle:
        head = handle.read(_HEADER_BYTES)
    suffix = path.suffix.lower()
    if suffix == ".ply":
        _check_ply(head, size)
    elif suffix == ".stl":
        _check_stl(head, size)
    elif suffix == ".vtk":
        _check_legacy_vtk(head, size)
    elif suffix == ".vtp":
        _check_xml_counts(head)


def _limit(count: int, most: int, what: str) -> None:
    if count < 0:
        raise HeaderError(f"the header gives a negative number of {what}")
    if count > most:
        raise HeaderError(f"the header claims {count:,} {what} (at most {most:,} are read)")


def _claim(count: int, least_bytes: int, available: int, what: str) -> None:
    if count * least_bytes > available:
        raise HeaderError(f"the header claims {count:,} {what} but the file is too small to hold them "
                          "(truncated or corrupt)")


def _check_ply(head: bytes, size: int) -> None:
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise HeaderError("not a PLY file (no 'ply' ... 'end_header' header)")
    newline = head.find(b"\n", end)
    body = size - (newline + 1 if newline >= 0 else end + len(b"end_header"))
    lines = head[:end].decode("ascii", "replace").splitlines()
    binary = False
    elements: list[list] = []  # [name, count, least bytes per element]
    for line in lines:
        words = line.split()
        if not words:
            continue
        if words[0] == "format" and len(words) >= 2:
            binary = words[1] != "ascii"
        elif words[0] == "element" and len(words) == 3:
            try:
                count = int(words[2])
            except ValueError:
                raise HeaderError(f"the element count {words[2][:20]!r} is not a whole number") from None
            elements.append([words[1], count, 0])
        elif words[0] == "property" and elements:
            if binary:
                type_name = words[2] if words[1:2] == ["list"] and len(words) > 2 else words[1] if len(words) > 1 else ""
                if type_name not in _PLY_SIZES:
                    raise HeaderError(f"unknown PLY property type {type_name[:20]!r}")
                elements[-1][2] += _PLY_SIZES[type_name]
            else:
                elements[-1][2] += 2  # a digit and a separator at least
    needed = 0
    for name, count, least in elements:
        most = MAX_POINTS if name == "vertex" else MAX_CELLS
        _limit(count, most, f"{name} elements")
        needed += count * max(least, 1)
    if needed > body:
        raise HeaderError("the header claims more elements than the file holds (truncated or corrupt)")


def _check_stl(head: bytes, size: int) -> None:
    if head[:5].lower() == b"solid" and b"facet" in head[:_HEADER_BYTES]:
        return  # ASCII STL: read as a stream
    if size < 84:
        raise HeaderError("binary STL shorter than its 84-byte header")
    (count,) = struct.unpack("<I", head[80:84])
    _limit(count, MAX_CELLS, "triangles")
    _claim(count, 50, size - 84, "triangles")


_VTK_COUNT = re.compile(rb"^(POINTS|POLYGONS|CELLS|TRIANGLE_STRIPS|LINES|VERTICES)\s+(\d+)\s*(\S*)", re.MULTILINE)
_VTK_SIZES = {b"float": 4, b"double": 8, b"int": 4, b"vtktypeint64": 8, b"unsigned_char": 1, b"char": 1,
              b"short": 2, b"unsigned_short": 2, b"unsigned_int": 4, b"long": 8, b"unsigned_long": 8}


def _check_legacy_vtk(head: bytes, size: int) -> None:
    binary = b"\nBINARY" in head[:1024].upper()
    for match in _VTK_COUNT.finditer(head):
        keyword, count = match.group(1), int(match.group(2))
        if keyword == b"POINTS":
            _limit(count, MAX_POINTS, "points")
            least = 3 * _VTK_SIZES.get(match.group(3).lower(), 4) if binary else 6
            _claim(count, least, size, "points")
        else:
            _limit(count, MAX_CELLS, "cells")
            _claim(count, 4 if binary else 2, size, "cells")


_XML_COUNT = re.compile(rb'Number(?:Of)?(Points|Polys|Cells|Strips|Lines|Verts)\s*=\s*"(-?\d+)"')


def _check_xml_counts(head: bytes) -> None:
    for match in _XML_COUNT.finditer(head):
        count = int(match.group(2))
        _limit(count, MAX_POINTS if match.group(1) == b"Points" else MAX_CELLS, match.group(1).decode().lower())
