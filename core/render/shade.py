"""Fused numba per-pixel kernels: perspective-correct barycentrics of the visible face, then
shading (SH of the interpolated normal), flat shading (SH of the face's own normal, as a ray
tracer shows micro-triangles without shading normals), normal, depth or mask, with an
analytic backward.

Barycentrics are recomputed from the vertex positions (so they carry gradients, as in
nvdiffrast's rasterize backward): with clip coordinates (x_i, y_i, w_i) of the face's vertices and
pixel NDC (x, y), u_i = x_i - x w_i, t_i = y_i - y w_i, beta_i = u_j t_k - u_k t_j (i, j, k cyclic)
and b_i = beta_i / sum(beta). The backward scatters vertex gradients into per-slot buffers (:mod:`core.render.slots`).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..runtime.borrow import borrow
from ..runtime.jit import kernel
from .lighting import (face_normal, flat_backward, interp_normal, sh_grad, shade_normal,
                       unnormalized_grad)
from .pixel import add_vertex_grad, bary, bary_backward, clip_xyw
from .prefetch import ahead

MODE_SHADED, MODE_NORMAL, MODE_DEPTH, MODE_MASK, MODE_FLAT = 0, 1, 2, 3, 4
MODES = {"shaded": MODE_SHADED, "normal": MODE_NORMAL, "depth": MODE_DEPTH, "mask": MODE_MASK,
         "flat": MODE_FLAT}


@kernel(nogil=True, error_model="numpy", fastmath={"contract", "arcp"})
def shade_forward(verts, faces, vn, noff, mvp, tri, mode, qa, qb, qk, out, lo, hi):
    """out (B, H, W, C) (zeros on entry) <- per-pixel value of ``mode``. Vertex normals are
    vn[:, noff:noff + 3] (``verts`` and ``vn`` may be one packed (N, 6) array: fewer cache misses)."""
    verts, faces, vn, mvp = borrow(verts), borrow(faces), borrow(vn), borrow(mvp)
    tri, out = borrow(tri), borrow(out)
    qa, qb, qk = borrow(qa), borrow(qb), borrow(qk)
    nb, height, width = tri.shape
    for row in range(lo, hi):  # rows of all views: nb * height
        b, r = row // height, row % height
        m = mvp[b]
        y = 1.0 - (r + 0.5) * (2.0 / height)
        for c in range(width):
            ahead(tri[b, r], faces, verts, c)
            f = tri[b, r, c]
            if f < 0:
                continue
            if mode == MODE_MASK:
                out[b, r, c, 0] = 1.0
                continue
            i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
            if mode == MODE_FLAT:
                n0, n1, n2 = face_normal(verts, i0, i1, i2)[:3]
                for ch in range(3):
                    out[b, r, c, ch] = shade_normal(qa, qb, qk, ch, n0, n1, n2)
                continue
            x = (c + 0.5) * (2.0 / width) - 1.0
            x0, y0, w0 = clip_xyw(verts, m, i0)
            x1, y1, w1 = clip_xyw(verts, m, i1)
            x2, y2, w2 = clip_xyw(verts, m, i2)
            b0, b1, b2, s, u0, u1, u2, t0, t1, t2 = bary(x0, y0, w0, x1, y1, w1, x2, y2, w2, x, y)
            if mode == MODE_DEPTH:
                out[b, r, c, 0] = b0 * w0 + b1 * w1 + b2 * w2
                continue
            n0, n1, n2, inv = interp_normal(vn, noff, i0, i1, i2, b0, b1, b2)
            if mode == MODE_NORMAL:
                out[b, r, c, 0], out[b, r, c, 1], out[b, r, c, 2] = n0, n1, n2
            else:
                for ch in range(3):
                    out[b, r, c, ch] = shade_normal(qa, qb, qk, ch, n0, n1, n2)
    return 0


@njit(inline="always")
def pixel_backward(verts, faces, vn, noff, m, f, x, y, mode, qa, qb, qk, g0, g1, g2, gv, gn):
    """Accumulate the gradients of one pixel's value (upstream g0..g2) into gv / gn."""
    i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
    if mode == MODE_FLAT:
        flat_backward(verts, i0, i1, i2, qa, qb, g0, g1, g2, gv)
        return
    x0, y0, w0 = clip_xyw(verts, m, i0)
    x1, y1, w1 = clip_xyw(verts, m, i1)
    x2, y2, w2 = clip_xyw(verts, m, i2)
    b0, b1, b2, s, u0, u1, u2, t0, t1, t2 = bary(x0, y0, w0, x1, y1, w1, x2, y2, w2, x, y)
    ew0 = ew1 = ew2 = 0.0
    if mode == MODE_DEPTH:
        gb0, gb1, gb2 = g0 * w0, g0 * w1, g0 * w2
        ew0, ew1, ew2 = g0 * b0, g0 * b1, g0 * b2
    else:
        n0, n1, n2, inv = interp_normal(vn, noff, i0, i1, i2, b0, b1, b2)
        if mode == MODE_NORMAL:
            h0, h1, h2 = g0, g1, g2
        else:
            h0, h1, h2 = sh_grad(qa, qb, g0, g1, g2, n0, n1, n2)
        k0, k1, k2 = unnormalized_grad(n0, n1, n2, inv, h0, h1, h2)
        gn[i0, noff + 0] += b0 * k0
        gn[i0, noff + 1] += b0 * k1
        gn[i0, noff + 2] += b0 * k2
        gn[i1, noff + 0] += b1 * k0
        gn[i1, noff + 1] += b1 * k1
        gn[i1, noff + 2] += b1 * k2
        gn[i2, noff + 0] += b2 * k0
        gn[i2, noff + 1] += b2 * k1
        gn[i2, noff + 2] += b2 * k2
        gb0 = k0 * vn[i0, noff] + k1 * vn[i0, noff + 1] + k2 * vn[i0, noff + 2]
        gb1 = k0 * vn[i1, noff] + k1 * vn[i1, noff + 1] + k2 * vn[i1, noff + 2]
        gb2 = k0 * vn[i2, noff] + k1 * vn[i2, noff + 1] + k2 * vn[i2, noff + 2]
    gu0, gu1, gu2, gt0, gt1, gt2 = bary_backward(gb0, gb1, gb2, b0, b1, b2, s, u0, u1, u2, t0, t1, t2)
    add_vertex_grad(gv, i0, m, gu0, gt0, ew0 - x * gu0 - y * gt0)
    add_vertex_grad(gv, i1, m, gu1, gt1, ew1 - x * gu1 - y * gt1)
    add_vertex_grad(gv, i2, m, gu2, gt2, ew2 - x * gu2 - y * gt2)


@kernel(nogil=True, error_model="numpy", fastmath={"contract", "arcp"})
def shade_backward(verts, faces, vn, noff, mvp, tri, mode, qa, qb, qk, gout, gv, gn, lo, hi):
    """gv (SLOTS, N, >=3), gn (SLOTS, N, noff + 3) <- per-slot parts of d(sum gout * out)/d verts
    and d/d vertex normals (may be one packed (SLOTS, N, 6) buffer with noff = 3)."""
    verts, faces, vn, mvp, tri = borrow(verts), borrow(faces), borrow(vn), borrow(mvp), borrow(tri)
    qa, qb, qk, gout, gv, gn = borrow(qa), borrow(qb), borrow(qk), borrow(gout), borrow(gv), borrow(gn)
    nb, height, width = tri.shape
    nslot = gv.shape[0]
    nrows = nb * height
    for k in range(lo, hi):  # slots
        gvk, gnk = gv[k], gn[k]
        gvk[:] = 0.0
        gnk[:] = 0.0  # (a no-op repeat when gv and gn are one packed buffer)
        for row in range(k * nrows // nslot, (k + 1) * nrows // nslot):
            b, r = row // height, row % height
            m = mvp[b]
            y = 1.0 - (r + 0.5) * (2.0 / height)
            for c in range(width):
                ahead(tri[b, r], faces, verts, c)
                ahead(tri[b, r], faces, gvk, c)
                f = tri[b, r, c]
                if f < 0:
                    continue
                x = (c + 0.5) * (2.0 / width) - 1.0
                g0 = np.float64(gout[b, r, c, 0])
                g1 = np.float64(gout[b, r, c, 1]) if gout.shape[3] > 1 else 0.0
                g2 = np.float64(gout[b, r, c, 2]) if gout.shape[3] > 2 else 0.0
                if g0 == 0.0 and g1 == 0.0 and g2 == 0.0:
                    continue
                pixel_backward(verts, faces, vn, noff, m, f, x, y, mode, qa, qb, qk, g0, g1, g2, gvk, gnk)
    return 0
