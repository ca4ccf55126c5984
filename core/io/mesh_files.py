"""Read triangle meshes (the formats of ``core.io.inputs`` that we read ourselves: PLY, OBJ,
STL, a micro-mesh glTF) and write binary PLY, without Blender.

Used by tests, benchmarks and ``batch.py``. Polygons are triangulated as fans
``(v0, vi, vi+1)``; what the file holds is checked (``MeshFileError`` names the problem), and
the mesh itself by ``TriMesh`` (finite coordinates, index ranges).
"""
from __future__ import annotations

from .inputs import read_mesh
from .ply import write_ply
from .polygons import MeshFileError

__all__ = ["MeshFileError", "read_mesh", "write_ply"]
