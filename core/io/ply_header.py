"""A PLY file's header: its format, elements and properties (types checked), and the
element properties the reader needs (vertex positions, the face index list)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .polygons import MeshFileError

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


@dataclass
class PlyProp:
    name: str
    dtype: str                     # value type (numpy code without byte order)
    count_dtype: str | None = None  # list length type; None for a scalar property


@dataclass
class PlyElement:
    name: str
    count: int
    props: list[PlyProp] = field(default_factory=list)

    @property
    def has_list(self) -> bool:
        return any(p.count_dtype is not None for p in self.props)


def _ply_type(name: str, path: Path) -> str:
    try:
        return _PLY_TYPES[name]
    except KeyError:
        raise MeshFileError(f"{path}: unknown PLY property type {name!r}") from None


def parse_header(data: bytes, path: Path) -> tuple[str, list[PlyElement], int]:
    if not data.startswith(b"ply"):
        raise MeshFileError(f"{path}: not a PLY file (missing 'ply' magic)")
    end = data.find(b"end_header")
    if end < 0:
        raise MeshFileError(f"{path}: PLY header has no end_header")
    nl = data.find(b"\n", end)
    body_start = len(data) if nl < 0 else nl + 1
    header = data[:end].decode("ascii", errors="replace").replace("\r", "").split("\n")
    fmt = None
    elements: list[PlyElement] = []
    for line in header[1:]:
        tok = line.split()
        if not tok or tok[0] in ("comment", "obj_info"):
            continue
        if tok[0] == "format":
            if len(tok) < 2 or tok[1] not in ("ascii", "binary_little_endian", "binary_big_endian"):
                raise MeshFileError(f"{path}: unsupported PLY format {' '.join(tok[1:])!r}")
            fmt = tok[1]
        elif tok[0] == "element":
            try:
                elements.append(PlyElement(tok[1], int(tok[2])))
            except (IndexError, ValueError):
                raise MeshFileError(f"{path}: bad PLY element line {line!r}") from None
            if elements[-1].count < 0:
                raise MeshFileError(f"{path}: negative element count in {line!r}")
        elif tok[0] == "property":
            if not elements:
                raise MeshFileError(f"{path}: PLY property before any element")
            if len(tok) == 5 and tok[1] == "list":
                elements[-1].props.append(
                    PlyProp(tok[4], _ply_type(tok[3], path), _ply_type(tok[2], path)))
            elif len(tok) == 3:
                elements[-1].props.append(PlyProp(tok[2], _ply_type(tok[1], path)))
            else:
                raise MeshFileError(f"{path}: bad PLY property line {line!r}")
        else:
            raise MeshFileError(f"{path}: unexpected PLY header line {line!r}")
    if fmt is None:
        raise MeshFileError(f"{path}: PLY header has no format line")
    return fmt, elements, body_start


def vertex_xyz(arr: np.ndarray, el: PlyElement, path: Path) -> np.ndarray:
    names = [p.name for p in el.props]
    if not all(c in names for c in "xyz"):
        raise MeshFileError(f"{path}: PLY vertex element lacks x/y/z")
    return np.stack([np.asarray(arr[c], dtype=np.float64) for c in "xyz"], axis=1)


def face_list_prop(el: PlyElement, path: Path) -> PlyProp:
    lists = [p for p in el.props if p.count_dtype is not None]
    for p in lists:
        if p.name in ("vertex_indices", "vertex_index"):
            return p
    if len(lists) == 1:
        return lists[0]
    raise MeshFileError(f"{path}: PLY face element has no vertex_indices list")
