"""Counting micro-triangles of per-face levels, and the ±1 rule across edges and one-rings."""
from __future__ import annotations

import numpy as np


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


def effective_micro_triangles(levels: np.ndarray, face_adjacency: np.ndarray) -> int:
    """Micro-triangles the tessellation really has: a face at level l loses 2**(l-1) of them
    along each edge whose neighbour is one level coarser (the edge decimation that keeps the
    surface crack-free). ``face_adjacency``: (F, 3) neighbour across each edge, -1 none."""
    lv = np.asarray(levels, dtype=np.int64)
    nb = neighbour_levels(lv, face_adjacency)
    coarser = (nb == lv[:, None] - 1).sum(axis=1)
    return int(np.sum(4 ** lv) - np.sum(coarser * (1 << np.maximum(lv - 1, 0))))


def neighbour_levels(levels: np.ndarray, face_adjacency: np.ndarray) -> np.ndarray:
    """(F, 3): the level across each edge of each face, its own level across a boundary."""
    lv = np.asarray(levels, dtype=np.int64)
    adj = np.asarray(face_adjacency)
    return np.where(adj >= 0, lv[np.maximum(adj, 0)], lv[:, None])


def balance_levels_adjacency(face_adjacency: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Raise the lower side until faces across manifold edges differ by at most one level."""
    lv = np.asarray(levels, dtype=np.int64).copy()
    while True:
        new = np.maximum(lv, neighbour_levels(lv, face_adjacency).max(axis=1) - 1)
        if np.array_equal(new, lv):
            return lv
        lv = new
