"""Scan-like test meshes, as a scanner's reconstruction leaves them: an irregular triangulation
whose density varies over the surface, a figure's large forms with fine carved detail,
noise along the normals, a few tiny holes where the scanner saw nothing, and (the bust)
non-manifold edges left by merging scans.

The surface is star-shaped: r(u) for unit directions u, large Gaussian lobes on an ellipsoid
plus ridges. Its triangulation is the convex hull of random points on the unit sphere, drawn
denser in some regions than in others, moved out to r(u)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull


def _directions(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) unit vectors, about twice as dense near a few random centres as elsewhere."""
    centres = rng.normal(size=(5, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    out = np.empty((0, 3))
    while len(out) < n:
        u = rng.normal(size=(2 * n, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        keep = rng.random(len(u)) < 0.5 + 0.5 * np.exp(-8 * (1 - (u @ centres.T).max(1)))
        out = np.concatenate([out, u[keep]])
    return out[:n]


def _figure(u: np.ndarray, lobes: list[tuple], rng_seed: int) -> np.ndarray:
    """The radius along each direction: an upright ellipsoid, Gaussian ``lobes`` (direction,
    height, width) and carved ridges."""
    r = 1.0 / np.sqrt((u[:, 0] / 0.55) ** 2 + (u[:, 1] / 0.45) ** 2 + (u[:, 2] / 1.0) ** 2)
    for d, height, width in lobes:
        d = np.asarray(d, float) / np.linalg.norm(d)
        r += height * np.exp(-(1 - u @ d) / width)
    rng = np.random.default_rng(rng_seed)
    for _ in range(6):
        k = rng.normal(size=3)
        k /= np.linalg.norm(k)
        r += 0.006 * np.sin(rng.uniform(20, 45) * (u @ k) + rng.uniform(0, 2 * np.pi))
    return r


def _surface(faces: int, lobes: list[tuple], noise: float, seed: int
             ) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = _directions(faces // 2 + 2, rng)
    f = ConvexHull(u).simplices.astype(np.int64)
    a = u[f]
    out = np.einsum("ij,ij->i", np.cross(a[:, 1] - a[:, 0], a[:, 2] - a[:, 0]), a.mean(1))
    f[out < 0] = f[out < 0][:, ::-1]                  # outward
    r = _figure(u, lobes, seed + 1) + rng.normal(0.0, noise, len(u))
    return u * r[:, None], f


def _cut(v: np.ndarray, f: np.ndarray, holes: int, faces_each: int, rng: np.random.Generator
         ) -> np.ndarray:
    """``f`` less ``holes`` small holes of about ``faces_each`` faces (those nearest a random
    face's centre)."""
    c = v[f].mean(1)
    gone = np.zeros(len(f), bool)
    for k in rng.choice(len(f), holes, replace=False):
        gone[np.argsort(np.linalg.norm(c - c[k], axis=1))[:faces_each]] = True
    return f[~gone]


_STATUE = [((0, 0, 1), 0.35, 0.02), ((0.8, 0, 0.55), 0.25, 0.03), ((-0.8, 0, 0.55), 0.25, 0.03),
           ((0.5, 0.3, -0.6), 0.18, 0.05), ((-0.5, 0.3, -0.6), 0.18, 0.05),
           ((0, 1, 0.2), 0.08, 0.1)]
_BUST = [((0, 0, 1), 0.45, 0.03), ((0, 0.25, 0.95), 0.06, 0.004), ((1, 0, -0.3), 0.35, 0.15),
         ((-1, 0, -0.3), 0.35, 0.15), ((0, 1, 0.7), 0.05, 0.01)]


def scanned_statue(faces: int = 20_000, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A scanned statue of about ``faces`` faces with two tiny holes (3 faces each)."""
    v, f = _surface(faces, _STATUE, 6e-4, seed)
    return v, _cut(v, f, 2, 3, np.random.default_rng(seed + 2))


def nonmanifold_bust(faces: int = 109_000, fins: int = 40, seed: int = 5
                     ) -> tuple[np.ndarray, np.ndarray]:
    """A scanned bust of about ``faces`` faces with ``fins`` non-manifold edges: each a
    third face on an edge of the surface (no two sharing a vertex), whose far corner stands
    a little off it, as merged scans leave them."""
    v, f = _surface(faces, _BUST, 3e-4, seed)
    rng = np.random.default_rng(seed + 2)
    chosen, used = [], np.zeros(len(v), bool)
    for k in rng.permutation(len(f)):
        a, b = f[k, 0], f[k, 1]
        if len(chosen) == fins:
            break
        if not (used[a] or used[b]):
            used[[a, b]] = True
            chosen.append((a, b, f[k, 2]))
    e = np.array(chosen, dtype=np.int64)
    n = np.cross(v[e[:, 1]] - v[e[:, 0]], v[e[:, 2]] - v[e[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    apex = v[e[:, 2]] + 0.5 * np.linalg.norm(v[e[:, 1]] - v[e[:, 0]], axis=1)[:, None] * n
    fins_f = np.column_stack([e[:, 1], e[:, 0], len(v) + np.arange(len(e))])
    return np.vstack([v, apex]), np.vstack([f, fins_f])
