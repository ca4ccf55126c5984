"""One pixel's view of one face, compiled inline: a vertex's clip coordinates, the pixel's
perspective-correct barycentrics, their backward, and a clip-space gradient taken back to the
vertex through the view matrix.

With clip coordinates (x_i, y_i, w_i) of the face's vertices and pixel NDC (x, y),
u_i = x_i - x w_i, t_i = y_i - y w_i, beta_i = u_j t_k - u_k t_j (i, j, k cyclic) and
b_i = beta_i / sum(beta).
"""
from __future__ import annotations

import numpy as np
from numba import njit

_TINY = 1e-300


@njit(inline="always")
def clip_xyw(verts, m, i):
    vx, vy, vz = np.float64(verts[i, 0]), np.float64(verts[i, 1]), np.float64(verts[i, 2])
    return (m[0, 0] * vx + m[0, 1] * vy + m[0, 2] * vz + m[0, 3],
            m[1, 0] * vx + m[1, 1] * vy + m[1, 2] * vz + m[1, 3],
            m[3, 0] * vx + m[3, 1] * vy + m[3, 2] * vz + m[3, 3])


@njit(inline="always")
def bary(x0, y0, w0, x1, y1, w1, x2, y2, w2, x, y):
    u0, u1, u2 = x0 - x * w0, x1 - x * w1, x2 - x * w2
    t0, t1, t2 = y0 - y * w0, y1 - y * w1, y2 - y * w2
    s0 = u1 * t2 - u2 * t1
    s1 = u2 * t0 - u0 * t2
    s2 = u0 * t1 - u1 * t0
    s = s0 + s1 + s2
    if abs(s) < _TINY:
        s = _TINY
    inv = 1.0 / s
    return s0 * inv, s1 * inv, s2 * inv, s, u0, u1, u2, t0, t1, t2


@njit(inline="always")
def bary_backward(g0, g1, g2, b0, b1, b2, s, u0, u1, u2, t0, t1, t2):
    gs = g0 * b0 + g1 * b1 + g2 * b2
    h0, h1, h2 = (g0 - gs) / s, (g1 - gs) / s, (g2 - gs) / s
    gu0 = h2 * t1 - h1 * t2
    gu1 = h0 * t2 - h2 * t0
    gu2 = h1 * t0 - h0 * t1
    gt0 = h1 * u2 - h2 * u1
    gt1 = h2 * u0 - h0 * u2
    gt2 = h0 * u1 - h1 * u0
    return gu0, gu1, gu2, gt0, gt1, gt2


@njit(inline="always")
def add_vertex_grad(buf, i, m, gx, gy, gw):
    for j in range(3):
        buf[i, j] += m[0, j] * gx + m[1, j] * gy + m[3, j] * gw
