"""The shading's per-pixel work as Triton kernels, the CUDA twin of ``shade.py``'s numba ones:
perspective-correct barycentrics of the visible face, SH shading of the interpolated normal
("shaded") or of the face's own normal ("flat"); the helpers its backward shares.

The backward (``triton_shade_grad``) runs one lane per face over that face's pixels (in pixel
order); the corners' parts are then summed per vertex by ``corner_sums``. Every sum is made in
a fixed order, with no atomics, so the gradient is the same on every run. Float64 arithmetic,
as the numba kernels.

Arrays: verts, vn (N, 3) float; faces (M, 3) int64; mvp (B, 16) float64; tri (B * H * W,) int32
(-1: background); q (30,) float64, per channel [k, b0, b1, b2, a00, a11, a22, a01, a02, a12]
(``sh.SH_QUADRATIC``).
"""
from __future__ import annotations

from .lighting import NORMAL_EPS
from .triton_kernels import tl, triton

if triton is not None:
    NORMAL_EPS_F = tl.constexpr(NORMAL_EPS)  # kernels read only constexpr globals

    @triton.jit
    def vertex_at(ptr, i, mask):
        """Row ``i`` of an (N, 3) array as three float64 values per lane."""
        return (tl.load(ptr + i * 3, mask=mask, other=0.0).to(tl.float64),
                tl.load(ptr + i * 3 + 1, mask=mask, other=0.0).to(tl.float64),
                tl.load(ptr + i * 3 + 2, mask=mask, other=0.0).to(tl.float64))

    @triton.jit
    def clip_row(m_ptr, r: tl.constexpr, vx, vy, vz, mask):
        """Row r of mvp (per lane's view, ``m_ptr`` offset by 16 b) applied to (v, 1)."""
        return (((tl.load(m_ptr + 4 * r, mask=mask, other=0.0) * vx
                  + tl.load(m_ptr + 4 * r + 1, mask=mask, other=0.0) * vy)
                 + tl.load(m_ptr + 4 * r + 2, mask=mask, other=0.0) * vz)
                + tl.load(m_ptr + 4 * r + 3, mask=mask, other=1.0))

    @triton.jit
    def _shade(q_ptr, c: tl.constexpr, n0, n1, n2):
        o = q_ptr + 10 * c
        return (tl.load(o) + tl.load(o + 1) * n0 + tl.load(o + 2) * n1 + tl.load(o + 3) * n2
                + tl.load(o + 4) * n0 * n0 + tl.load(o + 5) * n1 * n1 + tl.load(o + 6) * n2 * n2
                + 2.0 * (tl.load(o + 7) * n0 * n1 + tl.load(o + 8) * n0 * n2
                         + tl.load(o + 9) * n1 * n2))

    @triton.jit
    def _sh_grad_c(q_ptr, c: tl.constexpr, g, n0, n1, n2):
        o = q_ptr + 10 * c
        a00, a11, a22 = tl.load(o + 4), tl.load(o + 5), tl.load(o + 6)
        a01, a02, a12 = tl.load(o + 7), tl.load(o + 8), tl.load(o + 9)
        return (g * (tl.load(o + 1) + 2.0 * (a00 * n0 + a01 * n1 + a02 * n2)),
                g * (tl.load(o + 2) + 2.0 * (a01 * n0 + a11 * n1 + a12 * n2)),
                g * (tl.load(o + 3) + 2.0 * (a02 * n0 + a12 * n1 + a22 * n2)))

    @triton.jit
    def unnormalized_grad(q_ptr, g0, g1, g2, n0, n1, n2, inv):
        """Gradient w.r.t. v of the shading of n = v / |v| (upstream g0..g2 per channel)."""
        a0, a1, a2 = _sh_grad_c(q_ptr, 0, g0, n0, n1, n2)
        b0, b1, b2 = _sh_grad_c(q_ptr, 1, g1, n0, n1, n2)
        c0, c1, c2 = _sh_grad_c(q_ptr, 2, g2, n0, n1, n2)
        h0, h1, h2 = a0 + b0 + c0, a1 + b1 + c1, a2 + b2 + c2
        d = n0 * h0 + n1 * h1 + n2 * h2
        return (h0 - n0 * d) * inv, (h1 - n1 * d) * inv, (h2 - n2 * d) * inv

    @triton.jit
    def face_normal(v_ptr, i0, i1, i2, mask):
        p0, p1, p2 = vertex_at(v_ptr, i0, mask)
        ax, ay, az = vertex_at(v_ptr, i1, mask)
        bx, by, bz = vertex_at(v_ptr, i2, mask)
        ax, ay, az, bx, by, bz = ax - p0, ay - p1, az - p2, bx - p0, by - p1, bz - p2
        nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
        inv = 1.0 / tl.sqrt(nx * nx + ny * ny + nz * nz + NORMAL_EPS_F)
        return nx * inv, ny * inv, nz * inv, inv, ax, ay, az, bx, by, bz

    @triton.jit
    def pixel(v_ptr, vn_ptr, m_ptr, i0, i1, i2, x, y, mask):
        """Barycentrics of pixel NDC (x, y) on a face and its interpolated unit normal."""
        p0, p1, p2 = vertex_at(v_ptr, i0, mask)
        x0, y0, w0 = clip_row(m_ptr, 0, p0, p1, p2, mask), clip_row(m_ptr, 1, p0, p1, p2, mask), \
            clip_row(m_ptr, 3, p0, p1, p2, mask)
        p0, p1, p2 = vertex_at(v_ptr, i1, mask)
        x1, y1, w1 = clip_row(m_ptr, 0, p0, p1, p2, mask), clip_row(m_ptr, 1, p0, p1, p2, mask), \
            clip_row(m_ptr, 3, p0, p1, p2, mask)
        p0, p1, p2 = vertex_at(v_ptr, i2, mask)
        x2, y2, w2 = clip_row(m_ptr, 0, p0, p1, p2, mask), clip_row(m_ptr, 1, p0, p1, p2, mask), \
            clip_row(m_ptr, 3, p0, p1, p2, mask)
        u0, u1, u2 = x0 - x * w0, x1 - x * w1, x2 - x * w2
        t0, t1, t2 = y0 - y * w0, y1 - y * w1, y2 - y * w2
        s0, s1, s2 = u1 * t2 - u2 * t1, u2 * t0 - u0 * t2, u0 * t1 - u1 * t0
        s = s0 + s1 + s2
        s = tl.where(tl.abs(s) < 1e-300, 1e-300, s)
        b0, b1, b2 = s0 / s, s1 / s, s2 / s
        a0, a1, a2 = vertex_at(vn_ptr, i0, mask)
        c0, c1, c2 = vertex_at(vn_ptr, i1, mask)
        d0, d1, d2 = vertex_at(vn_ptr, i2, mask)
        n0 = b0 * a0 + b1 * c0 + b2 * d0
        n1 = b0 * a1 + b1 * c1 + b2 * d1
        n2 = b0 * a2 + b1 * c2 + b2 * d2
        inv = 1.0 / tl.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + NORMAL_EPS_F)
        return (b0, b1, b2, s, u0, u1, u2, t0, t1, t2, n0 * inv, n1 * inv, n2 * inv, inv,
                a0, a1, a2, c0, c1, c2, d0, d1, d2)

    @triton.jit
    def ndc(p, width, height):
        hw = width * height
        rem = p % hw
        r, c = (rem // width).to(tl.float64), (rem % width).to(tl.float64)
        zero = tl.zeros_like(rem).to(tl.float64)   # int + float would be float32
        fw, fh = zero + width, zero + height
        return p // hw, (c + 0.5) * (2.0 / fw) - 1.0, 1.0 - (r + 0.5) * (2.0 / fh)

    @triton.jit
    def shade_forward_kernel(v_ptr, vn_ptr, f_ptr, m_ptr, tri_ptr, q_ptr, out_ptr, n_pix,
                             width, height, FLAT: tl.constexpr, BLOCK: tl.constexpr):
        p = tl.program_id(0).to(tl.int64) * BLOCK + tl.arange(0, BLOCK)
        inb = p < n_pix
        face = tl.load(tri_ptr + p, mask=inb, other=-1).to(tl.int64)
        live = face >= 0
        i0 = tl.load(f_ptr + face * 3, mask=live, other=0)
        i1 = tl.load(f_ptr + face * 3 + 1, mask=live, other=0)
        i2 = tl.load(f_ptr + face * 3 + 2, mask=live, other=0)
        if FLAT:
            n0, n1, n2, _, _, _, _, _, _, _ = face_normal(v_ptr, i0, i1, i2, live)
        else:
            b, x, y = ndc(p, width, height)
            _, _, _, _, _, _, _, _, _, _, n0, n1, n2, _, _, _, _, _, _, _, _, _, _ = pixel(
                v_ptr, vn_ptr, m_ptr + b * 16, i0, i1, i2, x, y, live)
        for c in tl.static_range(3):
            val = tl.where(live, _shade(q_ptr, c, n0, n1, n2), 0.0)
            tl.store(out_ptr + p * 3 + c, val.to(out_ptr.dtype.element_ty), mask=inb)
