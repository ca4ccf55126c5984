"""Brute-force answers the compiled queries are checked against."""
from __future__ import annotations

import numpy as np


def segment_points(p, a, b):
    """Closest points on segments ab (row-wise)."""
    u = b - a
    uu = np.einsum("ij,ij->i", u, u)
    t = np.einsum("ij,ij->i", p - a, u) / np.where(uu > 0, uu, 1.0)
    t = np.clip(np.where(uu > 0, t, 0.0), 0, 1)
    return a + t[:, None] * u


def triangle_distances(q, v, f):
    """Distance from each point to every triangle, by a formulation independent of Ericson's:
    the plane foot where it lies inside a non-degenerate triangle, else the nearest edge point."""
    tri = v[f]
    qq = np.repeat(q, len(f), axis=0)
    a, b, c = (np.tile(tri[:, k], (len(q), 1)) for k in range(3))
    cands = [segment_points(qq, a, b), segment_points(qq, b, c), segment_points(qq, c, a)]
    d = np.stack([np.linalg.norm(x - qq, axis=1) for x in cands], 1).min(1)
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 1e-20 * np.einsum("ij,ij->i", b - a, b - a) * np.einsum("ij,ij->i", c - a, c - a)
    foot = qq - (np.einsum("ij,ij->i", qq - a, n) / np.where(ok, nn, 1.0))[:, None] * n
    inside = ok.copy()
    for x, y in ((a, b), (b, c), (c, a)):  # foot on the inner side of every edge
        inside &= np.einsum("ij,ij->i", np.cross(y - x, foot - x), n) >= 0
    d = np.where(inside, np.minimum(d, np.linalg.norm(foot - qq, axis=1)), d)
    return d.reshape(len(q), len(f))
