"""Procedural test shapes (icosahedron, icospheres, torus, noisy and finned spheres) as (V, F)
arrays.

Used by the tests and the benchmarks (and handy for quick experiments): real meshes come from
``../shared/meshes``; these are the built-in, license-free shapes with known geometry.
"""
from __future__ import annotations

import numpy as np

def icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """Unit icosahedron (12 vertices, 20 outward-oriented faces)."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], np.int64)
    return v / np.linalg.norm(v, axis=1, keepdims=True), f


def subdivided_icosahedron(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Icosahedron with each edge split into ``n`` segments (flat, not projected).

    10·n² + 2 vertices and 20·n² faces; vertices shared between faces are merged exactly.
    """
    if n < 1 or n >= 4096:
        raise ValueError("n must be in [1, 4095]")
    V, F = icosahedron()
    ii, jj = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = ii + jj <= n
    i, j = ii[keep], jj[keep]  # weights of corners 1 and 2; corner 0 gets n - i - j
    k = n - i - j
    local = -np.ones((n + 1, n + 1), np.int64)
    local[i, j] = np.arange(len(i))
    # Exact shared-vertex keys: sorted (corner id, weight) pairs, zero weights as id 12.
    w = np.stack([np.broadcast_to(k, (20, len(i))), np.broadcast_to(i, (20, len(i))),
                  np.broadcast_to(j, (20, len(i)))], axis=2)          # (20, p, 3)
    ids = np.where(w > 0, F[:, None, :], 12)
    pair = (ids << 12) | np.where(w > 0, w, 0)
    key = np.sort(pair, axis=2)
    key = (key[..., 0] << 32) | (key[..., 1] << 16) | key[..., 2]
    uniq, first, inv = np.unique(key.ravel(), return_index=True, return_inverse=True)
    pos = (w[..., :, None] * V[F][:, None, :, :]).sum(2) / n          # (20, p, 3)
    verts = pos.reshape(-1, 3)[first]
    gidx = inv.reshape(20, -1)
    a, b = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    up = a + b <= n - 1
    dn = a + b <= n - 2
    tri_up = np.stack([local[a[up], b[up]], local[a[up] + 1, b[up]], local[a[up], b[up] + 1]], 1)
    tri_dn = np.stack([local[a[dn] + 1, b[dn]], local[a[dn] + 1, b[dn] + 1], local[a[dn], b[dn] + 1]], 1)
    tri = np.concatenate([tri_up, tri_dn])
    faces = np.concatenate([gidx[fi][tri] for fi in range(20)])
    return verts, faces


def icosphere(n: int, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Subdivided icosahedron projected onto a sphere: 10·n² + 2 vertices."""
    v, f = subdivided_icosahedron(n)
    return radius * v / np.linalg.norm(v, axis=1, keepdims=True), f


def icosphere_with_vertices(n_vertices: int, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The icosphere whose vertex count is nearest ``n_vertices``."""
    return icosphere(max(1, round(((n_vertices - 2) / 10) ** 0.5)), radius)


def noisy_sphere(n_faces: int, amplitude: float = 0.05, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Icosphere with about ``n_faces`` faces, radius modulated by smooth random waves."""
    v, f = icosphere(max(1, round((n_faces / 20) ** 0.5)))
    rng = np.random.default_rng(seed)
    r = np.ones(len(v))
    for _ in range(12):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        r += amplitude / 4 * np.sin(rng.uniform(3, 25) * (v @ d) + rng.uniform(0, 2 * np.pi))
    return v * r[:, None], f


def finned_sphere(n_faces: int, fins: int = 40, holes: int = 60, height: float = 1.5,
                  seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """:func:`noisy_sphere` with triangular fins glued onto ``fins`` of its edges (each fin a
    third face on its edge, its apex ``height`` edge lengths out along the normal: that edge
    is non-manifold; no two fins share a vertex) and ``holes`` faces cut away (none touching
    a fin: its edge keeps three faces)."""
    v, f = noisy_sphere(n_faces, seed=seed)
    rng = np.random.default_rng(seed + 1)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    edges = np.unique(e, axis=0)
    chosen, used = [], np.zeros(len(v), bool)
    for a, b in edges[rng.permutation(len(edges))]:
        if len(chosen) == fins:
            break
        if not (used[a] or used[b]):
            used[[a, b]] = True
            chosen.append((a, b))
    fe = np.array(chosen, dtype=np.int64).reshape(-1, 2)
    mid = v[fe].mean(axis=1)
    length = np.linalg.norm(v[fe[:, 0]] - v[fe[:, 1]], axis=1)
    apex = mid + height * length[:, None] * mid / np.linalg.norm(mid, axis=1, keepdims=True)
    free = np.flatnonzero(~used[f].any(axis=1))
    cut = rng.choice(free, size=min(holes, len(free)), replace=False)
    kept = np.delete(f, cut, axis=0)
    fin_faces = np.column_stack([fe, len(v) + np.arange(len(fe))])
    return np.vstack([v, apex]), np.vstack([kept, fin_faces]).astype(np.int64)


def torus(n: int = 12, m: int = 8, major: float = 1.0, minor: float = 0.35) -> tuple[np.ndarray, np.ndarray]:
    """Closed genus-1 torus around +Z with ``2·n·m`` faces, outward oriented."""
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    th, ph = 2 * np.pi * i / n, 2 * np.pi * j / m
    v = np.stack([(major + minor * np.cos(ph)) * np.cos(th),
                  (major + minor * np.cos(ph)) * np.sin(th), minor * np.sin(ph)], -1).reshape(-1, 3)
    idx = lambda a, b: (a % n) * m + (b % m)  # noqa: E731
    q = [idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)]
    f = np.concatenate([np.stack([q[0], q[1], q[2]], -1).reshape(-1, 3),
                        np.stack([q[0], q[2], q[3]], -1).reshape(-1, 3)])
    return v, f.astype(np.int64)


def holed_plate(genus: int, k: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A closed genus-``genus`` solid: a one-voxel-thick plate of 3 × (2·genus + 1) unit voxels
    with a square hole through every second voxel of its middle row. Sharp 90° creases
    everywhere, flat faces between them (a CAD-like part). Each voxel face is split into
    k × k squares of two triangles; outward oriented, vertices merged exactly."""
    if genus < 0 or k < 1:
        raise ValueError("genus must be >= 0 and k >= 1")
    nx, ny = 2 * max(genus, 0) + 1, 3
    solid = np.ones((nx, ny), bool)
    solid[1:nx - 1:2, 1] = False
    quads = []
    for x, y in zip(*np.nonzero(solid)):
        for axis in range(3):
            for side in (0, 1):
                nb = [x, y, 0]
                nb[axis] += 1 if side else -1
                inside = (0 <= nb[0] < nx and 0 <= nb[1] < ny and nb[2] == 0
                          and solid[nb[0], nb[1]])
                if not inside:
                    quads.append((x, y, axis, side))
    s = np.linspace(0.0, 1.0, k + 1)
    a, b = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    corners = np.stack([np.stack([a, b], -1), np.stack([a + 1, b], -1),
                        np.stack([a + 1, b + 1], -1), np.stack([a, b + 1], -1)], 2).reshape(-1, 4, 2)
    pts, tris, base = [], [], 0
    for x, y, axis, side in quads:
        u_ax, v_ax = [(1, 2), (2, 0), (0, 1)][axis]
        p = np.zeros((len(corners), 4, 3))
        p[..., axis] = side
        p[..., u_ax] = s[corners[..., 0]]
        p[..., v_ax] = s[corners[..., 1]]
        p += np.array([x, y, 0.0])
        if not side:                     # the (u, v, axis) frame is right-handed: flip at side 0
            p = p[:, ::-1]
        pts.append(p.reshape(-1, 3))
        q = base + np.arange(len(corners) * 4).reshape(-1, 4)
        base += len(corners) * 4
        tris.append(np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]))
    P = np.concatenate(pts)
    key = np.round(P * k).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return P[first], inv.reshape(-1)[np.concatenate(tris)].astype(np.int64)
