"""One base triangle at one subdivision level: its micro-vertices' u-major and bird-curve
orders, barycentric weights and micro-triangles, and where its edge vertices snap towards a
coarser neighbour. Nothing here looks at a mesh (``core.micro.topology`` puts levels on one).

Conventions (``docs/micromesh-format.md``): a base triangle (W, U, V) = (v0, v1, v2) at level
ℓ holds micro-vertices at integer barycentrics (u, v), w = 2^ℓ − u − v. Edge ``i`` of a face
is ``(f[i], f[(i+1) % 3])``: edge 0 is v = 0 (W→U), edge 1 is w = 0 (U→V), edge 2 is u = 0
(V→W).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

# Levels a topology can hold: micromesh-tools writes up to 6; constructions and exports
# stop at BUILD_MAX_LEVEL, the ray-tracing hardware's and NVIDIA's reference reader's limit.
MAX_LEVEL = 7
BUILD_MAX_LEVEL = 5


class LevelError(ValueError):
    """Subdivision levels that cannot be used (wrong shape, out of range, unbalanced)."""


# ----------------------------------------------------------------------------- per level
def n_micro_vertices(level: int) -> int:
    """(2^ℓ+1)(2^ℓ+2)/2 micro-vertices in a level-ℓ triangle."""
    s = 1 << int(level)
    return (s + 1) * (s + 2) // 2


def n_micro_triangles(level: int) -> int:
    """4^ℓ micro-triangles in a level-ℓ triangle."""
    return 4 ** int(level)


def umajor_index(u, v, level: int):
    """u-major index u(2^ℓ+2) − u(u+1)/2 + v (vectorised over u, v)."""
    s = 1 << int(level)
    u = np.asarray(u, dtype=np.int64)
    v = np.asarray(v, dtype=np.int64)
    return u * (s + 2) - u * (u + 1) // 2 + v


@lru_cache(maxsize=None)
def level_grid_view(level: int) -> np.ndarray:
    """:func:`level_grid` cached and read-only, the level not checked (for hot loops)."""
    s = 1 << level
    u = np.repeat(np.arange(s + 1, dtype=np.int64), s + 1 - np.arange(s + 1))
    v = np.arange(len(u), dtype=np.int64) - umajor_index(u, 0, level)
    g = np.stack([u, v], axis=1)
    g.flags.writeable = False
    return g


def level_grid(level: int) -> np.ndarray:
    """(n, 2) integer (u, v) of the micro-vertices of a level, in u-major order."""
    _check_level(level)
    return level_grid_view(int(level)).copy()


def barycentric_weights(level: int) -> np.ndarray:
    """(n, 3) weights (w, u, v) / 2^ℓ of base vertices 0, 1, 2 for each u-major micro-vertex."""
    g = level_grid(level)
    s = float(1 << int(level))
    return np.stack([(s - g[:, 0] - g[:, 1]) / s, g[:, 0] / s, g[:, 1] / s], axis=1)


@lru_cache(maxsize=None)
def level_triangles_view(level: int) -> np.ndarray:
    """:func:`level_triangles` cached and read-only, the level not checked."""
    s = 1 << level
    g = level_grid_view(level)
    up = g[g.sum(1) <= s - 1]
    fl = g[g.sum(1) <= s - 2]
    u, v = up[:, 0], up[:, 1]
    t_up = np.stack([umajor_index(u, v, level), umajor_index(u + 1, v, level),
                     umajor_index(u, v + 1, level)], axis=1)
    u, v = fl[:, 0], fl[:, 1]
    t_fl = np.stack([umajor_index(u + 1, v, level), umajor_index(u + 1, v + 1, level),
                     umajor_index(u, v + 1, level)], axis=1)
    t = np.concatenate([t_up, t_fl]).astype(np.int64)
    t.flags.writeable = False
    return t


def level_triangles(level: int) -> np.ndarray:
    """(4^ℓ, 3) local u-major indices of the micro-triangles, wound like (W, U, V).

    The upright triangles (u, v), (u+1, v), (u, v+1) come first (u-major order of their
    corner), then the flipped ones (u+1, v), (u+1, v+1), (u, v+1).
    """
    _check_level(level)
    return level_triangles_view(int(level)).copy()


@lru_cache(maxsize=None)
def _bird_uv(level: int) -> np.ndarray:
    s = 1 << level
    W, U, V = (0, 0), (s, 0), (0, s)
    verts = [W, U, V]
    tris = [(W, U, V)]

    def mid(a, b):
        return ((a[0] + b[0]) // 2, (a[1] + b[1]) // 2)

    for k in range(1, level + 1):
        size = s >> (k - 1)
        for tri in tris:  # level k-1 triangles in bird order
            lo = (min(p[0] for p in tri), min(p[1] for p in tri))
            a, b, c = lo, (lo[0] + size, lo[1]), (lo[0], lo[1] + size)
            if set(tri) == {a, b, c}:  # upright in (u, v)
                verts += [mid(a, c), mid(c, b), mid(b, a)]
        nxt = []
        for w, u, v in tris:
            mwu, mwv, muv = mid(w, u), mid(w, v), mid(u, v)
            nxt += [(w, mwu, mwv), (mwv, muv, mwu), (mwu, u, muv), (muv, mwv, v)]
        tris = nxt
    out = np.array(verts, dtype=np.int64)
    out.flags.writeable = False
    return out


def bird_order(level: int) -> np.ndarray:
    """(n,) element i = u-major index of the i-th micro-vertex in bird-curve order."""
    _check_level(level)
    uv = _bird_uv(int(level))
    return umajor_index(uv[:, 0], uv[:, 1], level)


def bird_index(level: int) -> np.ndarray:
    """Inverse of :func:`bird_order`: element j = bird-curve index of u-major vertex j."""
    order = bird_order(level)
    inv = np.empty_like(order)
    inv[order] = np.arange(len(order))
    return inv


@lru_cache(maxsize=None)
def _edge_locals(level: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local indices of edge i's interior vertices at positions k = 1..2^ℓ−1 (from f[i]),
    the corner locals, and the interior locals (u-major)."""
    s = 1 << level
    k = np.arange(1, s, dtype=np.int64)
    e0 = umajor_index(k, 0, level)          # v = 0, from W to U: k = u
    e1 = umajor_index(s - k, k, level)      # w = 0, from U to V: k = v
    e2 = umajor_index(0, s - k, level)      # u = 0, from V to W: k = s - v
    edges = np.stack([e0, e1, e2]) if s > 1 else np.zeros((3, 0), dtype=np.int64)
    corners = np.array([0, umajor_index(s, 0, level), umajor_index(0, s, level)], dtype=np.int64)
    g = level_grid_view(level)
    w = s - g[:, 0] - g[:, 1]
    interior = np.flatnonzero((g[:, 0] > 0) & (g[:, 1] > 0) & (w > 0)).astype(np.int64)
    return edges, corners, interior


def _snapped_k(level: int) -> np.ndarray:
    """Edge position k = 1..2^ℓ−1 after snapping odd positions towards the nearer end
    (the exact middle of a level-1 edge goes to the edge's start, f[i])."""
    s = 1 << level
    k = np.arange(1, s, dtype=np.int64)
    return np.where(k % 2 == 1, np.where(2 * k <= s, k - 1, k + 1), k)


@lru_cache(maxsize=None)
def snap_targets_view(level: int, flags: int) -> np.ndarray:
    """:func:`snap_targets` cached and read-only, the arguments not checked."""
    s = 1 << level
    out = np.arange(n_micro_vertices(level), dtype=np.int64)
    if s == 1:
        return out
    edges, corners, _ = _edge_locals(level)
    ks = _snapped_k(level)
    for i in range(3):
        if (flags >> i) & 1:
            full = np.concatenate([[corners[i]], edges[i], [corners[(i + 1) % 3]]])
            out[edges[i]] = full[ks]
    out.flags.writeable = False
    return out


def snap_targets(level: int, flags: int) -> np.ndarray:
    """(n,) local u-major index each micro-vertex of a face stands for after edge decimation
    with the given flags (itself where not snapped)."""
    _check_level(level)
    return snap_targets_view(int(level), int(flags) & 7).copy()


def _check_level(level) -> None:
    if int(level) != level or not 0 <= int(level) <= MAX_LEVEL:
        raise LevelError(f"subdivision level must be an integer in 0..{MAX_LEVEL}, got {level}")
