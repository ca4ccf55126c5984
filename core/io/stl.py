"""STL meshes, binary and ASCII: a triangle soup (each triangle its own three vertices, as the
file lists them; the construction welds coincident vertices, not this reader).

Binary or ASCII is told by the size first: a binary file is exactly 84 + 50 n bytes for the n
triangles its header declares, and many binary files begin with "solid" too. A file of another
size that begins with "solid" and holds no zero byte is read as ASCII. What the file holds is
checked: a size that does not match, a facet without three vertices, a bad number, NaN or
infinite coordinates and no triangles at all are refused with one line (``MeshFileError``).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .polygons import MeshFileError

HEADER, RECORD = 84, 50
_BINARY = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
_WORD = re.compile(rb"^[ \t]*(\S+)(.*)$", re.M)


def read_stl(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """An STL file's corners (3 n, 3) float64, in the order the file lists them, and its
    triangles (n, 3): ``arange(3 n)``."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise MeshFileError(f"{path}: cannot read ({e.strerror or e})") from None
    declared = int(np.frombuffer(data, "<u4", 1, 80)[0]) if len(data) >= HEADER else -1
    if declared >= 0 and len(data) == HEADER + RECORD * declared:
        corners = _binary(data, declared)
    elif data.lstrip()[:5].lower() == b"solid" and b"\0" not in data:   # text
        corners = _ascii(data, path)
    elif declared < 0:
        raise MeshFileError(f"{path}: not an STL file ({len(data)} bytes: shorter than a "
                            f"binary STL's {HEADER}-byte header, and not ASCII 'solid')")
    elif len(data) < HEADER + RECORD * declared:
        raise MeshFileError(f"{path}: truncated binary STL: {declared} triangles take "
                            f"{HEADER + RECORD * declared} bytes, the file has {len(data)}")
    else:
        raise MeshFileError(f"{path}: binary STL with {len(data) - HEADER - RECORD * declared} "
                            f"bytes more than its {declared} triangles take (a damaged file)")
    n = len(corners) // 3
    if n == 0:
        raise MeshFileError(f"{path}: no triangles")
    bad = int((~np.isfinite(corners.reshape(n, 9))).any(axis=1).sum())
    if bad:
        raise MeshFileError(f"{path}: {bad} of {n} triangles have NaN or infinite coordinates")
    return corners, np.arange(3 * n, dtype=np.int64).reshape(n, 3)


def _binary(data: bytes, n: int) -> np.ndarray:
    rec = np.frombuffer(data, _BINARY, n, HEADER)
    return rec["v"].reshape(-1, 3).astype(np.float64)


def _ascii(data: bytes, path: Path) -> np.ndarray:
    """The vertices of an ASCII STL (one or more ``solid`` blocks), its structure checked:
    ``facet`` ``outer loop`` three ``vertex`` lines ``endloop`` ``endfacet``."""
    words, rests, lines = [], [], []
    for m in _WORD.finditer(data):
        words.append(m.group(1).lower())
        rests.append(m.group(2))
        lines.append(m.start())
    kinds = b"".join(_KIND.get(w, b"?") for w in words)
    if _GRAMMAR.fullmatch(kinds) is None:
        at = _PREFIX.match(kinds).end()      # after the last whole facet or solid
        at += next((j for j, c in enumerate(_FACET) if kinds[at + j:at + j + 1] != bytes([c])),
                   0)
        if at >= len(kinds):
            raise MeshFileError(f"{path}: truncated ASCII STL (it ends inside a solid)")
        line = data.count(b"\n", 0, lines[at]) + 1
        raise MeshFileError(f"{path}: not a valid ASCII STL at line {line} "
                            f"({words[at].decode('ascii', 'replace')!r})")
    vertex = [r for k, r in zip(kinds, rests) if k == ord("v")]
    try:
        v = np.array(b" ".join(vertex).split(), dtype=np.float64)
    except ValueError:
        raise MeshFileError(f"{path}: bad number in an ASCII STL vertex line") from None
    if v.size != 3 * len(vertex):
        raise MeshFileError(f"{path}: an ASCII STL vertex line without three numbers")
    return v.reshape(-1, 3)


# each line's first word as a letter; a file is one or more solids of whole facets
_FACET = b"fovvvle"          # facet, outer loop, vertex x3, endloop, endfacet
_GRAMMAR = re.compile(rb"(?:s(?:fovvvle)*n)+")
_PREFIX = re.compile(rb"(?:s(?:fovvvle)*n)*(?:s(?:fovvvle)*)?")
_KIND = {b"solid": b"s", b"facet": b"f", b"outer": b"o", b"vertex": b"v", b"endloop": b"l",
         b"endfacet": b"e", b"endsolid": b"n"}
