"""Check what a mesh file's header claims before VTK allocates for it.

VTK's readers size their arrays from the header's counts: a 278-byte PLY that claims
billions of vertices made VTK ask for 25 GB and abort the process. ``check_mesh_header``
reads only the header and refuses counts the file cannot hold (every element needs a
least number of bytes, in text or binary) or that exceed ``MAX_POINTS`` / ``MAX_CELLS``.
Formats without counts (OBJ, ASCII STL) have their faces counted in a stream of the file.

A model of more than ``MAX_MODEL_FACES`` faces is more than the matcher needs:
``fluorogui match`` on the real biplane images peaked at 0.30 GB with the 73,000-triangle
femoral component, 1.24 GB with a 300,000-triangle one, 1.48 GB with 400,000 and 2.6 GB with
1.2 million (the matcher's edge adjacency, silhouettes and point clouds grow with the
triangles). An implant model has some 10^4 to 10^5 triangles; a larger one is simplified
when read (``simplify``). Reading, simplifying and measuring the error cost memory too (a
model of 290,000 triangles peaked at 0.5 GB, 1.0 million at 1.1 GB, 2.0 million at 2.0 GB),
so models of more than ``MAX_SIMPLIFIED_FACES`` are refused with their size, to be decimated
first.
"""
from __future__ import annotations

import re
import struct
from pathlib import Path

MAX_POINTS = 20_000_000  # an implant model has some 10^4-10^5
MAX_CELLS = 40_000_000
MAX_MODEL_FACES = 250_000
MAX_SIMPLIFIED_FACES = 1_000_000
_HEADER_BYTES = 65536
_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


class HeaderError(ValueError):
    """The header is malformed or claims more than the file holds; the message says what."""


def check_mesh_header(path: Path) -> int:
    """The number of faces the mesh file at ``path`` holds, by its header (or a count in the
    file); raise HeaderError when the header is malformed or claims more points or cells than
    the file can hold."""
    size = path.stat().st_size
    with open(path, "rb") as handle:
        head = handle.read(_HEADER_BYTES)
    suffix = path.suffix.lower()
    if suffix == ".ply":
        faces = _check_ply(head, size)
    elif suffix == ".stl":
        faces = _check_stl(head, size)
        if faces is None:  # ASCII
            faces = _count_in_stream(path, b"endfacet")
    elif suffix == ".vtk":
        faces = _check_legacy_vtk(head, size)
    elif suffix == ".vtp":
        faces = _check_xml_counts(head)
    else:  # OBJ: one face a line starting "f "
        faces = _count_in_stream(path, b"\nf ")
    return faces


def check_model_faces(faces: int) -> None:
    """Raise HeaderError when a model has more faces than ``MAX_SIMPLIFIED_FACES``."""
    if faces > MAX_SIMPLIFIED_FACES:
        raise HeaderError(f"the model has {faces:,} faces, more than the {MAX_SIMPLIFIED_FACES:,} fluorogui "
                          f"simplifies (to {MAX_MODEL_FACES:,} or fewer for matching; an implant needs some 10^4 to "
                          "10^5, and each costs memory): decimate it first")


def _count_in_stream(path: Path, word: bytes, chunk: int = 1 << 22) -> int:
    """How often ``word`` occurs in the file, read a few MB at a time."""
    count, tail = 0, b""
    with open(path, "rb") as handle:
        while True:
            block = handle.read(chunk)
            if not block:
                return count
            data = tail + block
            count += data.count(word)
            tail = data[-(len(word) - 1):] if len(word) > 1 else b""  # a word split between blocks

def _limit(count: int, most: int, what: str) -> None:
    if count < 0:
        raise HeaderError(f"the header gives a negative number of {what}")
    if count > most:
        raise HeaderError(f"the header claims {count:,} {what} (at most {most:,} are read)")


def _claim(count: int, least_bytes: int, available: int, what: str) -> None:
    if count * least_bytes > available:
        raise HeaderError(f"the header claims {count:,} {what} but the file is too small to hold them "
                          "(truncated or corrupt)")


def _check_ply(head: bytes, size: int) -> int:
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
                listed = words[1:2] == ["list"] and len(words) > 2
                type_name = words[2] if listed else words[1] if len(words) > 1 else ""
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
    return sum(count for name, count, _ in elements if name == "face")


def _check_stl(head: bytes, size: int) -> int | None:
    """The binary STL's triangle count (None for an ASCII STL, read as a stream)."""
    if head[:5].lower() == b"solid" and b"facet" in head[:_HEADER_BYTES]:
        return None
    if size < 84:
        raise HeaderError("binary STL shorter than its 84-byte header")
    (count,) = struct.unpack("<I", head[80:84])
    _limit(count, MAX_CELLS, "triangles")
    _claim(count, 50, size - 84, "triangles")
    return count


_VTK_COUNT = re.compile(rb"^(POINTS|POLYGONS|CELLS|TRIANGLE_STRIPS|LINES|VERTICES)\s+(\d+)\s*(\S*)", re.MULTILINE)
_VTK_SIZES = {b"float": 4, b"double": 8, b"int": 4, b"vtktypeint64": 8, b"unsigned_char": 1, b"char": 1,
              b"short": 2, b"unsigned_short": 2, b"unsigned_int": 4, b"long": 8, b"unsigned_long": 8}


def _check_legacy_vtk(head: bytes, size: int) -> int:
    binary = b"\nBINARY" in head[:1024].upper()
    faces = 0
    for match in _VTK_COUNT.finditer(head):
        keyword, count = match.group(1), int(match.group(2))
        if keyword == b"POINTS":
            _limit(count, MAX_POINTS, "points")
            least = 3 * _VTK_SIZES.get(match.group(3).lower(), 4) if binary else 6
            _claim(count, least, size, "points")
        else:
            _limit(count, MAX_CELLS, "cells")
            _claim(count, 4 if binary else 2, size, "cells")
            if keyword in (b"POLYGONS", b"TRIANGLE_STRIPS", b"CELLS"):
                offsets = head[match.end():match.end() + 40].lstrip().startswith(b"OFFSETS")
                faces += max(0, count - 1) if offsets else count  # VTK 5 files count the offsets: one more
    return faces


_XML_COUNT = re.compile(rb'Number(?:Of)?(Points|Polys|Cells|Strips|Lines|Verts)\s*=\s*"(-?\d+)"')


def _check_xml_counts(head: bytes) -> int:
    faces = 0
    for match in _XML_COUNT.finditer(head):
        count = int(match.group(2))
        _limit(count, MAX_POINTS if match.group(1) == b"Points" else MAX_CELLS, match.group(1).decode().lower())
        faces += count if match.group(1) in (b"Polys", b"Strips", b"Cells") else 0
    return faces
