"""PLY meshes: read (ASCII and binary, either byte order; polygons as fans) and written
(binary little-endian, atomically). Pure-triangle binary PLYs (the common case, and every file
in ``shared/meshes``) are read with numpy structured dtypes, no per-face Python loop."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from .ply_header import PlyElement, face_list_prop, parse_header, vertex_xyz
from .polygons import MeshFileError, fan


def _read_ply_binary(data: bytes, pos: int, elements: list[PlyElement], bo: str, path: Path):
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
                verts = vertex_xyz(arr, el, path)
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
                fp = face_list_prop(el, path)
                faces = np.asarray(fixed[f"p{el.props.index(fp)}"]["v"], dtype=np.int64)
            continue
        # General path: walk the records one by one (polygons or mixed list lengths).
        polys = []
        fp = face_list_prop(el, path) if el.name == "face" else None
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
            faces = fan(polys)
    return verts, faces


def _read_ply_ascii(data: bytes, pos: int, elements: list[PlyElement], path: Path):
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
                fp = face_list_prop(el, path)
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
                faces = fan(np.stack(polys)) if len(lens) == 1 else fan(polys)
        except ValueError as e:
            if isinstance(e, MeshFileError):
                raise
            raise MeshFileError(f"{path}: bad number in ASCII PLY {el.name} data") from None
    return verts, faces


def read_ply(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A PLY file's vertex positions (n, 3) float64 and triangles (m, 3) int64 (indices not
    checked here: ``TriMesh`` does)."""
    data = path.read_bytes()
    fmt, elements, pos = parse_header(data, path)
    names = [e.name for e in elements]
    if "vertex" not in names or "face" not in names:
        raise MeshFileError(f"{path}: PLY needs 'vertex' and 'face' elements (point clouds unsupported)")
    if fmt == "ascii":
        return _read_ply_ascii(data, pos, elements, path)
    return _read_ply_binary(data, pos, elements, "<" if fmt == "binary_little_endian" else ">", path)


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
