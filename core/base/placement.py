"""A collapse's geometry, compiled: a triangle's shape quality and normal, a quadric's error at
a point, and the point a merged vertex goes to (the quadric's minimiser nearest a reference
point)."""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel
from .eigh3 import eigh3

FREE = 0.05          # eigenvalues of a quadric below FREE × the largest leave a direction free


@kernel(cache=True)
def triangle_quality(ax, ay, az, bx, by, bz, cx, cy, cz):  # pragma: no cover - compiled
    """2r/R of a triangle, and its (unnormalised) normal."""
    e0x, e0y, e0z = bx - ax, by - ay, bz - az
    e1x, e1y, e1z = cx - bx, cy - by, cz - bz
    e2x, e2y, e2z = ax - cx, ay - cy, az - cz
    nx = e0y * (-e2z) - e0z * (-e2y)
    ny = e0z * (-e2x) - e0x * (-e2z)
    nz = e0x * (-e2y) - e0y * (-e2x)
    l0 = np.sqrt(e0x * e0x + e0y * e0y + e0z * e0z)
    l1 = np.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
    l2 = np.sqrt(e2x * e2x + e2y * e2y + e2z * e2z)
    den = (l0 + l1 + l2) * l0 * l1 * l2
    q = 4.0 * (nx * nx + ny * ny + nz * nz) / den if den > 0 else 0.0
    return min(q, 1.0), nx, ny, nz


@kernel(cache=True)
def quadric_error_at(q, x, y, z):  # pragma: no cover - compiled
    """The quadric q (10 numbers, ``core.base.quadrics``) at the point (x, y, z)."""
    return (q[0] * x * x + 2 * q[1] * x * y + 2 * q[2] * x * z + 2 * q[3] * x
            + q[4] * y * y + 2 * q[5] * y * z + 2 * q[6] * y
            + q[7] * z * z + 2 * q[8] * z + q[9])


@kernel(cache=True)
def place(q, rx, ry, rz, scratch):  # pragma: no cover - compiled
    """The minimiser of the quadric q nearest to the reference point r (Lindstrom's SVD
    placement): exact in the directions the planes constrain (eigenvalues above ``FREE`` of
    the largest), r itself along the rest (a flat region, a crease line). ``scratch`` is (6, 3)."""
    a, vec = scratch[:3], scratch[3:]
    a[0, 0], a[0, 1], a[0, 2] = q[0], q[1], q[2]
    a[1, 0], a[1, 1], a[1, 2] = q[1], q[4], q[5]
    a[2, 0], a[2, 1], a[2, 2] = q[2], q[5], q[7]
    # residual g = -(A r + b)
    g0 = -(q[0] * rx + q[1] * ry + q[2] * rz + q[3])
    g1 = -(q[1] * rx + q[4] * ry + q[5] * rz + q[6])
    g2 = -(q[2] * rx + q[5] * ry + q[7] * rz + q[8])
    eigh3(a, vec)
    top = max(a[0, 0], a[1, 1], a[2, 2], 1e-300)
    x, y, z = rx, ry, rz
    for i in range(3):
        lam = a[i, i]
        if lam > FREE * top:
            c = (vec[0, i] * g0 + vec[1, i] * g1 + vec[2, i] * g2) / lam
            x += c * vec[0, i]
            y += c * vec[1, i]
            z += c * vec[2, i]
    return x, y, z
