"""Numba kernels of area-weighted unit vertex normals and their analytic backward (CPU
backend; ``numba_geometry.vertex_normals_numba`` runs them on tensors).

Same function as ``geometry.vertex_normals``: vn_v = normalize(sum over incident faces of
(v1 - v0) x (v2 - v0)). Both passes are race-free: faces are processed in parallel, vertices
gather from their incident corners (CSR from ``topology.vertex_corners``).
"""
from __future__ import annotations

import math

from ..runtime.jit import kernel
from .lighting import NORMAL_EPS


@kernel(nogil=True, error_model="numpy")
def _face_normals(verts, faces, fn, lo, hi):
    for f in range(lo, hi):
        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        ax, ay, az = verts[i1, 0] - verts[i0, 0], verts[i1, 1] - verts[i0, 1], verts[i1, 2] - verts[i0, 2]
        bx, by, bz = verts[i2, 0] - verts[i0, 0], verts[i2, 1] - verts[i0, 1], verts[i2, 2] - verts[i0, 2]
        fn[f, 0] = ay * bz - az * by
        fn[f, 1] = az * bx - ax * bz
        fn[f, 2] = ax * by - ay * bx
    return 0


@kernel(nogil=True, error_model="numpy")
def _vertex_forward(fn, ptr, corners, vn, inv, lo, hi):
    for v in range(lo, hi):
        s0 = s1 = s2 = 0.0
        for j in range(ptr[v], ptr[v + 1]):
            f = corners[j] // 3
            s0 += fn[f, 0]
            s1 += fn[f, 1]
            s2 += fn[f, 2]
        k = 1.0 / math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + NORMAL_EPS)
        inv[v] = k
        vn[v, 0], vn[v, 1], vn[v, 2] = s0 * k, s1 * k, s2 * k
    return 0


@kernel(nogil=True, error_model="numpy")
def _vertex_backward(gvn, vn, inv, graw, lo, hi):
    for v in range(lo, hi):
        d = vn[v, 0] * gvn[v, 0] + vn[v, 1] * gvn[v, 1] + vn[v, 2] * gvn[v, 2]
        for j in range(3):
            graw[v, j] = (gvn[v, j] - vn[v, j] * d) * inv[v]
    return 0


@kernel(nogil=True, error_model="numpy")
def _verts_backward(verts, faces, graw, ptr, corners, gverts, lo, hi):
    for v in range(lo, hi):
        s0 = s1 = s2 = 0.0
        for j in range(ptr[v], ptr[v + 1]):
            f, k = corners[j] // 3, corners[j] % 3
            i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
            g0 = graw[i0, 0] + graw[i1, 0] + graw[i2, 0]
            g1 = graw[i0, 1] + graw[i1, 1] + graw[i2, 1]
            g2 = graw[i0, 2] + graw[i1, 2] + graw[i2, 2]
            ax, ay, az = verts[i1, 0] - verts[i0, 0], verts[i1, 1] - verts[i0, 1], verts[i1, 2] - verts[i0, 2]
            bx, by, bz = verts[i2, 0] - verts[i0, 0], verts[i2, 1] - verts[i0, 1], verts[i2, 2] - verts[i0, 2]
            # d/d e1 = e2 x g, d/d e2 = g x e1; v0 gets minus both
            p0, p1, p2 = by * g2 - bz * g1, bz * g0 - bx * g2, bx * g1 - by * g0
            q0, q1, q2 = g1 * az - g2 * ay, g2 * ax - g0 * az, g0 * ay - g1 * ax
            if k == 1:
                s0 += p0
                s1 += p1
                s2 += p2
            elif k == 2:
                s0 += q0
                s1 += q1
                s2 += q2
            else:
                s0 -= p0 + q0
                s1 -= p1 + q1
                s2 -= p2 + q2
        gverts[v, 0], gverts[v, 1], gverts[v, 2] = s0, s1, s2
    return 0
