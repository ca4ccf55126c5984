"""Barycentric coordinates of points on triangles (closest points a query returned)."""
from __future__ import annotations

import numpy as np


def barycentrics(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(q, 3) barycentrics of ``points`` (q, 3) in the triangles ``corners`` (q, 3, 3), for
    points on their triangle (rounding is clipped away: each row is in [0, 1] and sums to 1);
    a degenerate triangle gives its centroid's."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    v0, v1, v2 = b - a, c - a, points - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    ok = np.abs(den) > 1e-300
    den = np.where(ok, den, 1.0)
    v = np.where(ok, (d11 * d20 - d01 * d21) / den, 1 / 3)
    w = np.where(ok, (d00 * d21 - d01 * d20) / den, 1 / 3)
    bary = np.clip(np.stack([1.0 - v - w, v, w], 1), 0.0, 1.0)
    return bary / bary.sum(1, keepdims=True)
