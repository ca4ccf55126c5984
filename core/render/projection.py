"""Projection of vertices to the screen, per view, into per-thread-slot scratch arrays (the
rasteriser's and the silhouette-edge pass's first step)."""
from __future__ import annotations

import numpy as np
from numba import njit

from ..runtime.jit import kernel
from ..runtime.threads import threads


@njit(inline="always")
def screen_area(sc, i0, i1, i2):
    """(twice the signed screen area, in front of the near plane, facing sign) of a face
    from projected vertices; the facing sign is 0 for degenerate or clipped faces."""
    x0, y0, x1, y1, x2, y2 = sc[i0, 0], sc[i0, 1], sc[i1, 0], sc[i1, 1], sc[i2, 0], sc[i2, 1]
    area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
    ok = sc[i0, 3] != 0.0 and sc[i1, 3] != 0.0 and sc[i2, 3] != 0.0
    return area, ok, (0 if not ok else (1 if area > 0 else (-1 if area < 0 else 0)))


@kernel()
def project(verts, m, width, height, sc):
    """sc[i] = (screen x, screen y, 1 / clip w, 1 if in front of the near plane else 0)."""
    hw, hh = 0.5 * width, 0.5 * height
    for i in range(verts.shape[0]):
        vx, vy, vz = np.float64(verts[i, 0]), np.float64(verts[i, 1]), np.float64(verts[i, 2])
        x = ((m[0, 0] * vx + m[0, 1] * vy) + m[0, 2] * vz) + m[0, 3]
        y = ((m[1, 0] * vx + m[1, 1] * vy) + m[1, 2] * vz) + m[1, 3]
        z = ((m[2, 0] * vx + m[2, 1] * vy) + m[2, 2] * vz) + m[2, 3]
        w = ((m[3, 0] * vx + m[3, 1] * vy) + m[3, 2] * vz) + m[3, 3]
        sc[i, 0] = (x / w + 1.0) * hw
        sc[i, 1] = (1.0 - y / w) * hh
        sc[i, 2] = 1.0 / w
        sc[i, 3] = 1.0 if (w > 0 and z >= -w) else 0.0
    return 0


def scratch(n_verts: int, n_faces: int, n_views: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-thread-slot projected vertices and per-face facing signs."""
    slots = max(1, min(threads(), n_views))
    return np.empty((slots, n_verts, 4), dtype=np.float64), np.empty((slots, n_faces), dtype=np.int8)
