"""The exact closest point on one triangle (Ericson's Voronoi-region method, float64), and on
a segment for degenerate (zero-area) triangles: compiled, called per point and triangle by
the closest-point traversal (:mod:`core.spatial.closest`), and per (point, triangle) pair by
:func:`pair_distances` and :func:`pair_closest`."""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel


def degenerate(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """(m,) which triangles (corners (m, 3) each) are collinear or repeat a corner: the sine²
    of the angle at A under 1e-20 (:func:`closest_on_triangle` treats those as segments)."""
    ab, ac = B - A, C - A
    n2 = np.einsum("ij,ij->i", *(2 * [np.cross(ab, ac)]))
    scale = np.einsum("ij,ij->i", ab, ab) * np.einsum("ij,ij->i", ac, ac)
    return n2 <= 1e-20 * scale


def pair_distances(points: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray
                   ) -> np.ndarray:
    """(n,) the distance from each of ``points`` (n, 3) to its own triangle (A, B, C: (n, 3)
    corners each), exact (not the nearest of all the triangles: :mod:`core.spatial.closest`)."""
    A, B, C = (np.ascontiguousarray(x, dtype=np.float64) for x in (A, B, C))
    out = np.empty(len(A))
    _pair_distances(np.ascontiguousarray(points, dtype=np.float64), A, B, C,
                    degenerate(A, B, C), out)
    return out


def pair_closest(points: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray
                 ) -> np.ndarray:
    """(n, 3) the closest point of its own triangle (A, B, C: (n, 3) corners each) to each of
    ``points`` (n, 3), exact."""
    A, B, C = (np.ascontiguousarray(x, dtype=np.float64) for x in (A, B, C))
    out = np.empty((len(A), 3))
    _pair_closest(np.ascontiguousarray(points, dtype=np.float64), A, B, C,
                  degenerate(A, B, C), out)
    return out


@kernel(cache=True)
def _pair_closest(P, A, B, C, flat, out):  # pragma: no cover - compiled
    for k in range(P.shape[0]):
        x, y, z, _ = closest_on_triangle(P[k, 0], P[k, 1], P[k, 2], A, B, C, flat, k)
        out[k, 0], out[k, 1], out[k, 2] = x, y, z


@kernel(cache=True)
def _pair_distances(P, A, B, C, flat, out):  # pragma: no cover - compiled
    for k in range(P.shape[0]):
        out[k] = np.sqrt(closest_on_triangle(P[k, 0], P[k, 1], P[k, 2], A, B, C, flat, k)[3])


@kernel(cache=True)
def closest_on_segment(px, py, pz, ax, ay, az, bx, by, bz):  # pragma: no cover - compiled
    """Closest point on segment ab: (x, y, z, squared distance)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    uu = ux * ux + uy * uy + uz * uz
    t = 0.0
    if uu > 0.0:
        t = ((px - ax) * ux + (py - ay) * uy + (pz - az) * uz) / uu
        t = min(1.0, max(0.0, t))
    x, y, z = ax + t * ux, ay + t * uy, az + t * uz
    dx, dy, dz = px - x, py - y, pz - z
    return x, y, z, dx * dx + dy * dy + dz * dz


@kernel(cache=True)
def closest_on_triangle(px, py, pz, A, B, C, flat, f):  # pragma: no cover - compiled
    """Closest point on triangle f (rows of A, B, C) to p: (x, y, z, squared distance)."""
    ax, ay, az = A[f, 0], A[f, 1], A[f, 2]
    bx, by, bz = B[f, 0], B[f, 1], B[f, 2]
    cx, cy, cz = C[f, 0], C[f, 1], C[f, 2]
    if flat[f]:  # (nearly) zero area: the region tests break down; it is its edges' union
        x, y, z, e = closest_on_segment(px, py, pz, ax, ay, az, bx, by, bz)
        x2, y2, z2, e2 = closest_on_segment(px, py, pz, bx, by, bz, cx, cy, cz)
        if e2 < e:
            x, y, z, e = x2, y2, z2, e2
        x2, y2, z2, e2 = closest_on_segment(px, py, pz, cx, cy, cz, ax, ay, az)
        if e2 < e:
            x, y, z, e = x2, y2, z2, e2
        return x, y, z, e
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    x, y, z = ax, ay, az
    if d1 <= 0.0 and d2 <= 0.0:                                   # vertex a
        x, y, z = ax, ay, az
    else:
        bpx, bpy, bpz = px - bx, py - by, pz - bz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        cpx, cpy, cpz = px - cx, py - cy, pz - cz
        d5 = abx * cpx + aby * cpy + abz * cpz
        d6 = acx * cpx + acy * cpy + acz * cpz
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:                                # vertex b
            x, y, z = bx, by, bz
        elif d6 >= 0.0 and d5 <= d6:                              # vertex c
            x, y, z = cx, cy, cz
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:               # edge ab
            den = d1 - d3
            v = d1 / den if den > 0.0 else 0.0
            x, y, z = ax + v * abx, ay + v * aby, az + v * abz
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:               # edge ac
            den = d2 - d6
            w = d2 / den if den > 0.0 else 0.0
            x, y, z = ax + w * acx, ay + w * acy, az + w * acz
        elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:    # edge bc
            den = (d4 - d3) + (d5 - d6)
            w = (d4 - d3) / den if den > 0.0 else 0.0
            x, y, z = bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz)
        else:                                                     # face interior
            den = va + vb + vc
            v = vb / den
            w = vc / den
            x, y, z = ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w
    dx, dy, dz = px - x, py - y, pz - z
    return x, y, z, dx * dx + dy * dy + dz * dz
