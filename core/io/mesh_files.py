"""Read PLY/OBJ/STL triangle meshes and write binary PLY, without Blender.

Used by tests, benchmarks and ``batch.py``. Polygons are triangulated as fans
``(v0, vi, vi+1)``; what the file holds is checked (``MeshFileError`` names the problem), and
the mesh itself by ``TriMesh`` (finite coordinates, index ranges).
"""
from __future__ import annotations

import os
from pathlib import Path

from ..mesh import MeshError, TriMesh
from .obj import read_obj
from .ply import read_ply, write_ply
from .stl import read_stl
from .polygons import MeshFileError

__all__ = ["MeshFileError", "read_mesh", "write_ply"]


def read_mesh(path: str | os.PathLike) -> TriMesh:
    """Read a ``.ply`` (ASCII or binary), ``.obj`` or ``.stl`` (ASCII or binary; a triangle
    soup, as the file lists it) file as a triangle mesh."""
    path = Path(path)
    if not path.is_file():
        raise MeshFileError(f"{path}: no such file")
    ext = path.suffix.lower()
    if ext == ".ply":
        verts, faces = read_ply(path)
    elif ext == ".obj":
        verts, faces = read_obj(path)
    elif ext == ".stl":
        verts, faces = read_stl(path)
    else:
        raise MeshFileError(f"{path}: unsupported mesh format {ext!r} (use .ply, .obj or .stl)")
    if verts is None or faces is None:
        raise MeshFileError(f"{path}: missing vertex or face data")
    try:
        return TriMesh(verts, faces)
    except MeshError as e:
        raise MeshFileError(f"{path}: {e}") from None
