"""Counting micro-triangles of per-face levels, and levels over one-rings (the ±1 rule
across edges is ``core.micro.levels``')."""
from __future__ import annotations

import numpy as np

from ..mesh.trimesh import TriMesh
from ..micro.levels import face_edge_levels


def ring_min_max(levels: np.ndarray, ring: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per face, min and max level over its one-ring (its own level where the ring is empty)."""
    ptr, idx = ring
    lo = levels.copy()
    hi = levels.copy()
    counts = np.diff(ptr)
    has = counts > 0
    if idx.size:
        vals = levels[idx]
        starts = ptr[:-1][has]
        lo[has] = np.minimum.reduceat(vals, starts)
        hi[has] = np.maximum.reduceat(vals, starts)
    return lo, hi


def micro_triangle_count(levels: np.ndarray) -> int:
    """Micro-triangles of the full subdivisions (before the crack-free edge decimation)."""
    return int(np.sum(4 ** np.asarray(levels, dtype=np.int64)))


def effective_micro_triangles(levels: np.ndarray, mesh: TriMesh) -> int:
    """Micro-triangles the tessellation really has: a face at level l loses 2**(l-1) of them
    along each edge where a face one level coarser lies (the edge decimation that keeps the
    surface crack-free, ``core.micro.levels.edge_flags``: all the faces of a non-manifold
    edge count)."""
    lv = np.asarray(levels, dtype=np.int64)
    coarser = (face_edge_levels(mesh, lv)[0] == lv[:, None] - 1).sum(axis=1)
    return int(np.sum(4 ** lv) - np.sum(coarser * (1 << np.maximum(lv - 1, 0))))
