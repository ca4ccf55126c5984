"""Read PLY/OBJ triangle meshes and write binary PLY, without Blender.

Used by tests, benchmarks and ``batch.py``. Polygons are triangulated as fans
``(v0, vi, vi+1)``. Pure-triangle binary PLYs (the common case, and every file in
``shared/meshes``) are read with numpy structured dtypes, no per-face Python loop.
"""
from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..mesh import MeshError, TriMesh


class MeshFileError(ValueError):
    """The file is not a mesh this reader understands (bad, truncated or unsupported)."""


_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


@dataclass
class _PlyProp:
    name: str
    dtype: str                     # value type (numpy code without byte order)
    count_dtype: str | None = None  # list length type; None for a scalar property


@dataclass
class _PlyElement:
    name: str
    count: int
    props: list[_PlyProp] = field(default_factory=list)

    @property
    def has_list(self) -> bool:
        return any(p.count_dtype is not None for p in self.props)


def _ply_type(name: str, path: Path) -> str:
    try:
        return _PLY_TYPES[name]
    except KeyError:
        raise MeshFileError(f"{path}: unknown PLY property type {name!r}") from None


def _parse_ply_header(data: bytes, path: Path) -> tuple[str, list[_PlyElement], int]:
    if not data.startswith(b"ply"):
        raise MeshFileError(f"{path}: not a PLY file (missing 'ply' magic)")
    end = data.find(b"end_header")
    if end < 0:
        raise MeshFileError(f"{path}: PLY header has no end_header")
    nl = data.find(b"\n", end)
    body_start = len(data) if nl < 0 else nl + 1
    header = data[:end].decode("ascii", errors="replace").replace("\r", "").split("\n")
    fmt = None
    elements: list[_PlyElement] = []
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
                elements.append(_PlyElement(tok[1], int(tok[2])))
            except (IndexError, ValueError):
                raise MeshFileError(f"{path}: bad PLY element line {line!r}") from None
            if elements[-1].count < 0:
                raise MeshFileError(f"{path}: negative element count in {line!r}")
        elif tok[0] == "property":
            if not elements:
                raise MeshFileError(f"{path}: PLY property before any element")
            if len(tok) == 5 and tok[1] == "list":
                elements[-1].props.append(
                    _PlyProp(tok[4], _ply_type(tok[3], path), _ply_type(tok[2], path)))
            elif len(tok) == 3:
                elements[-1].props.append(_PlyProp(tok[2], _ply_type(tok[1], path)))
            else:
                raise MeshFileError(f"{path}: bad PLY property line {line!r}")
        else:
            raise MeshFileError(f"{path}: unexpected PLY header line {line!r}")
    if fmt is None:
        raise MeshFileError(f"{path}: PLY header has no format line")
    return fmt, elements, body_start


def _fan(polys: list[np.ndarray] | np.ndarray, counts: np.ndarray | None = None) -> np.ndarray:
    """Triangulate polygons (rows of equal length, or a ragged list) as fans."""
    if isinstance(polys, np.ndarray):
        k = polys.shape[1]
        if k < 3:
            raise MeshFileError("face with fewer than 3 vertices")
        tris = [np.stack([polys[:, 0], polys[:, i], polys[:, i + 1]], axis=1) for i in range(1, k - 1)]
        return np.stack(tris, axis=1).reshape(-1, 3)
    out = []
    for p in polys:
        if len(p) < 3:
            raise MeshFileError("face with fewer than 3 vertices")
        out.append(np.stack([np.full(len(p) - 2, p[0]), p[1:-1], p[2:]], axis=1))
    return np.concatenate(out) if out else np.zeros((0, 3), np.int64)


def _vertex_xyz(arr: np.ndarray, el: _PlyElement, path: Path) -> np.ndarray:
    names = [p.name for p in el.props]
    if not all(c in names for c in "xyz"):
        raise MeshFileError(f"{path}: PLY vertex element lacks x/y/z")
    return np.stack([np.asarray(arr[c], dtype=np.float64) for c in "xyz"], axis=1)


def _face_list_prop(el: _PlyElement, path: Path) -> _PlyProp:
    lists = [p for p in el.props if p.count_dtype is not None]
    for p in lists:
        if p.name in ("vertex_indices", "vertex_index"):
            return p
    if len(lists) == 1:
        return lists[0]
    raise MeshFileError(f"{path}: PLY face element has no vertex_indices list")


def _read_ply_binary(data: bytes, pos: int, elements: list[_PlyElement], bo: str, path: Path):
    verts = faces = None
    buf = memoryview(data)
    for el in elements:
        if not el.has_list:
            dt = np.dtype([(p.name, bo + p.dtype) for p in el.props])
            size = dt.itemsize * el.count
            if pos + size > len(data):
                raise MeshFileError(f"{path}: truncated PLY ({el.name} data)")
            arr = np.frombuffer(buf[pos:pos + size], dtype=dt, count=el.count)
            pos += size
            if el.name == "vertex":
                verts = _vertex_xyz(arr, el, path)
            continue
        # Elements with lists: first try "every list has 3 entries" (a fixed record).
        fixed = None
        if el.count > 0:
            dt = np.dtype([(f"p{i}", bo + p.dtype) if p.count_dtype is None
                           else (f"p{i}", [("n", bo + p.count_dtype), ("v", bo + p.dtype, (3,))])
                           for i, p in enumerate(el.props)])
            size = dt.itemsize * el.count
            if pos + size <= len(data):
                arr = np.frombuffer(buf[pos:pos + size], dtype=dt, count=el.count)
                if all((arr[f"p{i}"]["n"] == 3).all() for i, p in enumerate(el.props)
                       if p.count_dtype is not None):
                    fixed, pos = arr, pos + size
        if fixed is not None:
            if el.name == "face":
                fp = _face_list_prop(el, path)
                faces = np.asarray(fixed[f"p{el.props.index(fp)}"]["v"], dtype=np.int64)
            continue
        # General path: walk the records one by one (polygons or mixed list lengths).
        polys = []
        fp = _face_list_prop(el, path) if el.name == "face" else None
        try:
            for _ in range(el.count):
                for p in el.props:
                    if p.count_dtype is None:
                        pos += np.dtype(p.dtype).itemsize
                        continue
                    cdt = np.dtype(bo + p.count_dtype)
                    n = int(np.frombuffer(buf[pos:pos + cdt.itemsize], dtype=cdt)[0])
                    pos += cdt.itemsize
                    vdt = np.dtype(bo + p.dtype)
                    if p is fp:
                        vals = np.frombuffer(buf[pos:pos + n * vdt.itemsize], dtype=vdt, count=n)
                        polys.append(vals.astype(np.int64))
                    pos += n * vdt.itemsize
        except (ValueError, IndexError):
            raise MeshFileError(f"{path}: truncated PLY ({el.name} data)") from None
        if pos > len(data):
            raise MeshFileError(f"{path}: truncated PLY ({el.name} data)")
        if fp is not None:
            faces = _fan(polys)
    return verts, faces


def _read_ply_ascii(data: bytes, pos: int, elements: list[_PlyElement], path: Path):
    lines = [ln for ln in data[pos:].decode("ascii", errors="replace").splitlines() if ln.strip()]
    verts = faces = None
    at = 0
    for el in elements:
        chunk = lines[at:at + el.count]
        if len(chunk) < el.count:
            raise MeshFileError(f"{path}: truncated ASCII PLY ({el.name} data)")
        at += el.count
        try:
            if el.name == "vertex":
                if el.has_list:
                    raise MeshFileError(f"{path}: PLY vertex element with list properties")
                vals = np.array(" ".join(chunk).split(), dtype=np.float64)
                if vals.size != el.count * len(el.props):
                    raise MeshFileError(f"{path}: wrong number of values in PLY vertex data")
                vals = vals.reshape(el.count, len(el.props))
                names = [p.name for p in el.props]
                if not all(c in names for c in "xyz"):
                    raise MeshFileError(f"{path}: PLY vertex element lacks x/y/z")
                verts = vals[:, [names.index(c) for c in "xyz"]]
            elif el.name == "face":
                fp = _face_list_prop(el, path)
                polys = []
                for ln in chunk:
                    tok = ln.split()
                    i = 0
                    for p in el.props:
                        if p.count_dtype is None:
                            i += 1
                            continue
                        n = int(tok[i])
                        if p is fp:
                            polys.append(np.array(tok[i + 1:i + 1 + n], dtype=np.int64))
                            if len(polys[-1]) != n:
                                raise MeshFileError(f"{path}: short face line {ln!r}")
                        i += 1 + n
                lens = {len(p) for p in polys}
                faces = _fan(np.stack(polys)) if len(lens) == 1 else _fan(polys)
        except ValueError as e:
            if isinstance(e, MeshFileError):
                raise
            raise MeshFileError(f"{path}: bad number in ASCII PLY {el.name} data") from None
    return verts, faces


def _read_ply(path: Path) -> tuple[np.ndarray, np.ndarray]:
    data = path.read_bytes()
    fmt, elements, pos = _parse_ply_header(data, path)
    names = [e.name for e in elements]
    if "vertex" not in names or "face" not in names:
        raise MeshFileError(f"{path}: PLY needs 'vertex' and 'face' elements (point clouds unsupported)")
    if fmt == "ascii":
        return _read_ply_ascii(data, pos, elements, path)
    return _read_ply_binary(data, pos, elements, "<" if fmt == "binary_little_endian" else ">", path)


def _read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    verts: list[list[float]] = []
    polys: list[np.ndarray] = []
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise MeshFileError(f"{path}: cannot read ({e})") from None
    for lineno, line in enumerate(text.splitlines(), 1):
        tok = line.split()
        if not tok:
            continue
        try:
            if tok[0] == "v":
                verts.append([float(t) for t in tok[1:4]])
                if len(verts[-1]) != 3:
                    raise ValueError
            elif tok[0] == "f":
                idx = np.array([int(t.split("/")[0]) for t in tok[1:]], dtype=np.int64)
                if (idx == 0).any() or len(idx) < 3:
                    raise ValueError
                # 1-based; negative indices count back from the vertices read so far.
                polys.append(np.where(idx < 0, len(verts) + idx, idx - 1))
        except ValueError:
            raise MeshFileError(f"{path}:{lineno}: bad OBJ line {line.strip()!r}") from None
    if not verts or not polys:
        raise MeshFileError(f"{path}: OBJ has no vertices or no faces")
    lens = {len(p) for p in polys}
    faces = _fan(np.stack(polys)) if len(lens) == 1 else _fan(polys)
    return np.asarray(verts, dtype=np.float64), faces


def read_mesh(path: str | os.PathLike) -> TriMesh:
    """Read a ``.ply`` (ASCII or binary) or ``.obj`` file as a triangle mesh."""
    path = Path(path)
    if not path.is_file():
        raise MeshFileError(f"{path}: no such file")
    ext = path.suffix.lower()
    if ext == ".ply":
        verts, faces = _read_ply(path)
    elif ext == ".obj":
        verts, faces = _read_obj(path)
    else:
        raise MeshFileError(f"{path}: unsupported mesh format {ext!r} (use .ply or .obj)")
    if verts is None or faces is None:
        raise MeshFileError(f"{path}: missing vertex or face data")
    try:
        return TriMesh(verts, faces)
    except MeshError as e:
        raise MeshFileError(f"{path}: {e}") from None


def write_ply(path: str | os.PathLike, vertices: np.ndarray, faces: np.ndarray, *,
              double: bool = False) -> None:
    """Write a binary little-endian PLY atomically (temp file + ``os.replace``).

    Coordinates are float32 unless ``double`` (float64, for exact round trips); faces int32.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must be (n, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must be (m, 3), got {f.shape}")
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError("face index out of range")
    if len(v) > np.iinfo(np.int32).max:
        raise ValueError("too many vertices for int32 PLY indices")
    ftype = "double" if double else "float"
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(v)}\nproperty {ftype} x\nproperty {ftype} y\nproperty {ftype} z\n"
              f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    rec = np.empty(len(f), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    rec["n"] = 3
    rec["v"] = f
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".", prefix=path.name,
                               suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(header.encode("ascii"))
            fh.write(v.astype("<f8" if double else "<f4").tobytes())
            fh.write(rec.tobytes())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
