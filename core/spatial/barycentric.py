"""Barycentric coordinates of points on triangles (closest points a query returned)."""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel


def barycentrics(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(q, 3) barycentrics of ``points`` (q, 3) in the triangles ``corners`` (q, 3, 3), for
    points on their triangle (rounding is clipped away: each row is in [0, 1] and sums to 1);
    a degenerate triangle gives its centroid's. Compiled (a fit round queries millions)."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    c = np.ascontiguousarray(corners, dtype=np.float64)
    out = np.empty((len(p), 3))
    _barycentrics(p, c, out)
    return out


@kernel(cache=True)
def _barycentrics(p, c, out):  # pragma: no cover - compiled
    for q in range(p.shape[0]):
        d00 = d01 = d11 = d20 = d21 = 0.0
        for k in range(3):
            v0 = c[q, 1, k] - c[q, 0, k]
            v1 = c[q, 2, k] - c[q, 0, k]
            v2 = p[q, k] - c[q, 0, k]
            d00 += v0 * v0
            d01 += v0 * v1
            d11 += v1 * v1
            d20 += v2 * v0
            d21 += v2 * v1
        den = d00 * d11 - d01 * d01
        if abs(den) > 1e-300:
            v = (d11 * d20 - d01 * d21) / den
            w = (d00 * d21 - d01 * d20) / den
        else:
            v = w = 1.0 / 3.0
        u = min(max(1.0 - v - w, 0.0), 1.0)
        v = min(max(v, 0.0), 1.0)
        w = min(max(w, 0.0), 1.0)
        s = u + v + w
        out[q, 0], out[q, 1], out[q, 2] = u / s, v / s, w / s
