"""The supplement's Algorithm 1 (in-optimisation, τ = 0.1) and Algorithm 2 (post-process,
τ = 0.03)."""
from __future__ import annotations

import numpy as np

from .counts import ring_min_max
from .criteria import LodError


def in_optimization_lod(levels: np.ndarray, level: int, min_level: int, gains: np.ndarray | None,
                        one_ring: tuple[np.ndarray, np.ndarray], tau: float = 0.1) -> np.ndarray:
    """Algorithm 1: levels after the subdivision from ``level`` to ``level + 1``.

    Below ``min_level`` every face goes on. From ``min_level``, a face at ``level`` goes on
    only if no face in its one-ring stopped earlier (all are ≥ ``level``) and its gain (the
    improvement level ``level`` brought over ``level - 1``) exceeds ``tau``. Level 0 has no
    gain to judge (there is no level −1), so with ``min_level`` 0 every face still goes on
    to level 1; Algorithm 2 may roll faces back to 0.
    """
    lv = np.asarray(levels, dtype=np.int64).copy()
    if level < max(min_level, 1):
        lv[:] = level + 1
        return lv
    if gains is None or len(gains) != len(lv):
        raise LodError("Algorithm 1 needs one gain per base face from min_level on")
    ring_lo, _ = ring_min_max(lv, one_ring)
    go = (lv == level) & (ring_lo >= level) & (np.asarray(gains) > tau)
    lv[go] = level + 1
    return lv


def post_process_lod(gains_by_level: dict[int, np.ndarray], max_level: int, min_level: int,
                     one_ring: tuple[np.ndarray, np.ndarray], tau: float = 0.03,
                     n_faces: int | None = None) -> np.ndarray:
    """Algorithm 2: roll faces back from a uniform ``max_level`` run.

    ``gains_by_level[l]`` is the improvement level ``l`` brings over ``l - 1`` per face. At
    ``max_level`` any face below ``tau`` rolls back; then, level by level down to
    ``min_level + 1``, a face at that level rolls back if its gain is below ``tau`` and no
    face in its one-ring stopped rolling back (all are ≤ that level).
    """
    if n_faces is None:
        n_faces = len(next(iter(gains_by_level.values())))
    lv = np.full(n_faces, max_level, dtype=np.int64)
    if max_level <= min_level:
        return lv
    lv[np.asarray(gains_by_level[max_level]) < tau] = max_level - 1
    level = max_level - 1
    while level > min_level:
        _, ring_hi = ring_min_max(lv, one_ring)
        back = (lv == level) & (ring_hi <= level) & (np.asarray(gains_by_level[level]) < tau)
        lv[back] = level - 1
        level -= 1
    return lv
