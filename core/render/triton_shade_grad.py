"""The shading's analytic backward as a Triton kernel (``triton_shade`` is the forward): one
lane per face sums the gradients of that face's pixels, in pixel order, per corner; the
corners' parts are summed per vertex by ``corner_sums``. No atomics: the same gradient on every
run. Float64 arithmetic, as ``shade.pixel_backward``.

Arrays as ``triton_shade``'s; ``order``, ``start``, ``count``: the covered pixels grouped by
face (``corner_sums.segments``); ``fg`` (M, 3, 6) float64 out: per face and corner, the
gradient w.r.t. the vertex and the vertex normal.
"""
from __future__ import annotations

from .triton_kernels import tl, triton

if triton is not None:
    from .triton_shade import face_normal, ndc, pixel, unnormalized_grad

    @triton.jit
    def _bary_backward(g0, g1, g2, b0, b1, b2, s, u0, u1, u2, t0, t1, t2):
        gs = g0 * b0 + g1 * b1 + g2 * b2
        h0, h1, h2 = (g0 - gs) / s, (g1 - gs) / s, (g2 - gs) / s
        return (h2 * t1 - h1 * t2, h0 * t2 - h2 * t0, h1 * t0 - h0 * t1,
                h1 * u2 - h2 * u1, h2 * u0 - h0 * u2, h0 * u1 - h1 * u0)

    @triton.jit
    def _to_vertex(m_ptr, gu, gt, gw, mask):
        """A clip-space gradient (x, y, w) taken back through the view matrix: (x, y, z)."""
        return (tl.load(m_ptr, mask=mask, other=0.0) * gu
                + tl.load(m_ptr + 4, mask=mask, other=0.0) * gt
                + tl.load(m_ptr + 12, mask=mask, other=0.0) * gw,
                tl.load(m_ptr + 1, mask=mask, other=0.0) * gu
                + tl.load(m_ptr + 5, mask=mask, other=0.0) * gt
                + tl.load(m_ptr + 13, mask=mask, other=0.0) * gw,
                tl.load(m_ptr + 2, mask=mask, other=0.0) * gu
                + tl.load(m_ptr + 6, mask=mask, other=0.0) * gt
                + tl.load(m_ptr + 14, mask=mask, other=0.0) * gw)

    @triton.jit
    def _pixel_grad(v_ptr, vn_ptr, m_ptr, q_ptr, i0, i1, i2, p, g0, g1, g2, width, height, run):
        """One pixel's shading gradient (upstream g0..g2): w.r.t. the three vertices (9
        values) and the three vertex normals (9); zero where not ``run``."""
        b, x, y = ndc(p, width, height)
        mb = m_ptr + b * 16
        b0, b1, b2, s, u0, u1, u2, t0, t1, t2, n0, n1, n2, inv, a0, a1, a2, c0, c1, c2, \
            d0, d1, d2 = pixel(v_ptr, vn_ptr, mb, i0, i1, i2, x, y, run)
        k0, k1, k2 = unnormalized_grad(q_ptr, g0, g1, g2, n0, n1, n2, inv)
        k0, k1, k2 = tl.where(run, k0, 0.0), tl.where(run, k1, 0.0), tl.where(run, k2, 0.0)
        gu0, gu1, gu2, gt0, gt1, gt2 = _bary_backward(
            k0 * a0 + k1 * a1 + k2 * a2, k0 * c0 + k1 * c1 + k2 * c2,
            k0 * d0 + k1 * d1 + k2 * d2, b0, b1, b2, s, u0, u1, u2, t0, t1, t2)
        v0x, v0y, v0z = _to_vertex(mb, gu0, gt0, -x * gu0 - y * gt0, run)
        v1x, v1y, v1z = _to_vertex(mb, gu1, gt1, -x * gu1 - y * gt1, run)
        v2x, v2y, v2z = _to_vertex(mb, gu2, gt2, -x * gu2 - y * gt2, run)
        return (v0x, v0y, v0z, v1x, v1y, v1z, v2x, v2y, v2z,
                b0 * k0, b0 * k1, b0 * k2, b1 * k0, b1 * k1, b1 * k2, b2 * k0, b2 * k1, b2 * k2)

    @triton.jit
    def _flat_grad(v_ptr, q_ptr, i0, i1, i2, g0, g1, g2, mask):
        """The gradient of the shading of a face's own normal (upstream summed over its
        pixels) w.r.t. its three vertices (9 values)."""
        n0, n1, n2, inv, ax, ay, az, bx, by, bz = face_normal(v_ptr, i0, i1, i2, mask)
        k0, k1, k2 = unnormalized_grad(q_ptr, g0, g1, g2, n0, n1, n2, inv)
        # cross = a x b: d/da = b x k, d/db = k x a; vertex 0 moves both a and b
        v1x, v1y, v1z = by * k2 - bz * k1, bz * k0 - bx * k2, bx * k1 - by * k0
        v2x, v2y, v2z = k1 * az - k2 * ay, k2 * ax - k0 * az, k0 * ay - k1 * ax
        return -(v1x + v2x), -(v1y + v2y), -(v1z + v2z), v1x, v1y, v1z, v2x, v2y, v2z

    @triton.jit
    def _store_corner(fg_ptr, face, k: tl.constexpr, gx, gy, gz, nx, ny, nz, mask):
        o = fg_ptr + face * 18 + 6 * k
        tl.store(o, gx, mask=mask)
        tl.store(o + 1, gy, mask=mask)
        tl.store(o + 2, gz, mask=mask)
        tl.store(o + 3, nx, mask=mask)
        tl.store(o + 4, ny, mask=mask)
        tl.store(o + 5, nz, mask=mask)

    @triton.jit
    def shade_backward_kernel(v_ptr, vn_ptr, f_ptr, m_ptr, order_ptr, start_ptr, count_ptr,
                              gout_ptr, q_ptr, fg_ptr, n_faces, width, height,
                              FLAT: tl.constexpr, BLOCK: tl.constexpr):
        """fg (M, 3, 6) <- per face and corner, d(sum gout * image)/d (vertex, vertex normal),
        summed over the face's pixels ``order[start[f]:start[f] + count[f]]``."""
        face = tl.program_id(0).to(tl.int64) * BLOCK + tl.arange(0, BLOCK)
        live = face < n_faces
        i0 = tl.load(f_ptr + face * 3, mask=live, other=0)
        i1 = tl.load(f_ptr + face * 3 + 1, mask=live, other=0)
        i2 = tl.load(f_ptr + face * 3 + 2, mask=live, other=0)
        start = tl.load(start_ptr + face, mask=live, other=0)
        count = tl.load(count_ptr + face, mask=live, other=0)
        z = tl.zeros((BLOCK,), tl.float64)
        v0x, v0y, v0z, v1x, v1y, v1z, v2x, v2y, v2z = z, z, z, z, z, z, z, z, z
        n0x, n0y, n0z, n1x, n1y, n1z, n2x, n2y, n2z = z, z, z, z, z, z, z, z, z
        gs0, gs1, gs2 = z, z, z
        n_max = tl.max(count, axis=0)
        j = 0
        while j < n_max:
            run = j < count
            p = tl.load(order_ptr + start + j, mask=run, other=0)
            g0 = tl.load(gout_ptr + p * 3, mask=run, other=0.0).to(tl.float64)
            g1 = tl.load(gout_ptr + p * 3 + 1, mask=run, other=0.0).to(tl.float64)
            g2 = tl.load(gout_ptr + p * 3 + 2, mask=run, other=0.0).to(tl.float64)
            if FLAT:
                gs0, gs1, gs2 = gs0 + g0, gs1 + g1, gs2 + g2
            else:
                a0x, a0y, a0z, a1x, a1y, a1z, a2x, a2y, a2z, m0x, m0y, m0z, m1x, m1y, m1z, \
                    m2x, m2y, m2z = _pixel_grad(v_ptr, vn_ptr, m_ptr, q_ptr, i0, i1, i2, p, g0,
                                                g1, g2, width, height, run)
                v0x, v0y, v0z = v0x + a0x, v0y + a0y, v0z + a0z
                v1x, v1y, v1z = v1x + a1x, v1y + a1y, v1z + a1z
                v2x, v2y, v2z = v2x + a2x, v2y + a2y, v2z + a2z
                n0x, n0y, n0z = n0x + m0x, n0y + m0y, n0z + m0z
                n1x, n1y, n1z = n1x + m1x, n1y + m1y, n1z + m1z
                n2x, n2y, n2z = n2x + m2x, n2y + m2y, n2z + m2z
            j += 1
        if FLAT:
            v0x, v0y, v0z, v1x, v1y, v1z, v2x, v2y, v2z = _flat_grad(
                v_ptr, q_ptr, i0, i1, i2, gs0, gs1, gs2, live)
        _store_corner(fg_ptr, face, 0, v0x, v0y, v0z, n0x, n0y, n0z, live)
        _store_corner(fg_ptr, face, 1, v1x, v1y, v1z, n1x, n1y, n1z, live)
        _store_corner(fg_ptr, face, 2, v2x, v2y, v2z, n2x, n2y, n2z, live)
