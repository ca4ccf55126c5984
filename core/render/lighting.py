"""One pixel's lighting for the shading kernels (``shade``), inlined into them: second-order
spherical harmonics of a unit normal, the normal interpolated from the vertices' or a face's
own, and their backward to the normal and to the face's corners."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

NORMAL_EPS = 1e-20
"""Added to squared lengths before normalising, so that zero vectors give 0, never NaN (small
enough to be negligible for real faces, large enough that float32 backward cannot overflow).
Both backends use it (``geometry``, the Triton kernels)."""


@njit(inline="always")
def shade_normal(qa, qb, qk, ch, n0, n1, n2):
    a = qa[ch]
    return (qk[ch] + qb[ch, 0] * n0 + qb[ch, 1] * n1 + qb[ch, 2] * n2
            + a[0, 0] * n0 * n0 + a[1, 1] * n1 * n1 + a[2, 2] * n2 * n2
            + 2.0 * (a[0, 1] * n0 * n1 + a[0, 2] * n0 * n2 + a[1, 2] * n1 * n2))


@njit(inline="always")
def interp_normal(vn, o, i0, i1, i2, b0, b1, b2):
    n0 = b0 * vn[i0, o] + b1 * vn[i1, o] + b2 * vn[i2, o]
    n1 = b0 * vn[i0, o + 1] + b1 * vn[i1, o + 1] + b2 * vn[i2, o + 1]
    n2 = b0 * vn[i0, o + 2] + b1 * vn[i1, o + 2] + b2 * vn[i2, o + 2]
    inv = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + NORMAL_EPS)
    return n0 * inv, n1 * inv, n2 * inv, inv


@njit(inline="always")
def sh_grad(qa, qb, g0, g1, g2, n0, n1, n2):
    """Gradient of the three SH-shaded channels (upstream g0..g2) w.r.t. the unit normal."""
    h0 = h1 = h2 = 0.0
    for ch in range(3):
        gc = g0 if ch == 0 else (g1 if ch == 1 else g2)
        a = qa[ch]
        h0 += gc * (qb[ch, 0] + 2.0 * (a[0, 0] * n0 + a[0, 1] * n1 + a[0, 2] * n2))
        h1 += gc * (qb[ch, 1] + 2.0 * (a[1, 0] * n0 + a[1, 1] * n1 + a[1, 2] * n2))
        h2 += gc * (qb[ch, 2] + 2.0 * (a[2, 0] * n0 + a[2, 1] * n1 + a[2, 2] * n2))
    return h0, h1, h2


@njit(inline="always")
def unnormalized_grad(n0, n1, n2, inv, h0, h1, h2):
    """Through the normalisation n = v / |v| (inv = 1 / |v|): the gradient w.r.t. v."""
    d = n0 * h0 + n1 * h1 + n2 * h2
    return (h0 - n0 * d) * inv, (h1 - n1 * d) * inv, (h2 - n2 * d) * inv


@njit(inline="always")
def face_normal(verts, i0, i1, i2):
    """Unit normal of a face (cross product of its edges from vertex 0), 1/|cross|, the edges."""
    ax = np.float64(verts[i1, 0]) - np.float64(verts[i0, 0])
    ay = np.float64(verts[i1, 1]) - np.float64(verts[i0, 1])
    az = np.float64(verts[i1, 2]) - np.float64(verts[i0, 2])
    bx = np.float64(verts[i2, 0]) - np.float64(verts[i0, 0])
    by = np.float64(verts[i2, 1]) - np.float64(verts[i0, 1])
    bz = np.float64(verts[i2, 2]) - np.float64(verts[i0, 2])
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz + NORMAL_EPS)
    return nx * inv, ny * inv, nz * inv, inv, ax, ay, az, bx, by, bz


@njit(inline="always")
def flat_backward(verts, i0, i1, i2, qa, qb, g0, g1, g2, gv):
    """Gradient of the SH shading of a face's own normal w.r.t. its three corners."""
    n0, n1, n2, inv, ax, ay, az, bx, by, bz = face_normal(verts, i0, i1, i2)
    h0, h1, h2 = sh_grad(qa, qb, g0, g1, g2, n0, n1, n2)
    k0, k1, k2 = unnormalized_grad(n0, n1, n2, inv, h0, h1, h2)
    # cross = a x b: d/da = b x k, d/db = k x a; vertex 0 moves both a and b.
    pa0, pa1, pa2 = by * k2 - bz * k1, bz * k0 - bx * k2, bx * k1 - by * k0
    pb0, pb1, pb2 = k1 * az - k2 * ay, k2 * ax - k0 * az, k0 * ay - k1 * ax
    gv[i1, 0] += pa0
    gv[i1, 1] += pa1
    gv[i1, 2] += pa2
    gv[i2, 0] += pb0
    gv[i2, 1] += pb1
    gv[i2, 2] += pb2
    gv[i0, 0] -= pa0 + pb0
    gv[i0, 1] -= pa1 + pb1
    gv[i0, 2] -= pa2 + pb2
