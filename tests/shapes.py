"""Procedural test meshes as TriMesh (thin wrappers over core.mesh.primitives)."""
from __future__ import annotations

from core.mesh import primitives
from core.mesh.trimesh import TriMesh


def icosahedron() -> TriMesh:
    """Unit icosahedron, 20 outward faces."""
    return TriMesh(*primitives.icosahedron())


def icosphere(levels: int, radius: float = 1.0) -> TriMesh:
    """Unit icosphere with 20·4^levels faces (each edge split into 2^levels segments)."""
    return TriMesh(*primitives.icosphere(2 ** levels, radius))


def torus(n: int = 12, m: int = 8, major: float = 1.0, minor: float = 0.35) -> TriMesh:
    """Closed genus-1 torus with 2·n·m faces."""
    return TriMesh(*primitives.torus(n, m, major, minor))
