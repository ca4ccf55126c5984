"""The antialiasing walk across sub-pixel faces (``torch_antialias._walk``) as one Triton
kernel: each pair of pixels walks from its occluding face across the neighbours its pixel
segment crosses until it meets a silhouette edge, all pairs in parallel, instead of one round
of a dozen small torch kernels per step."""
from __future__ import annotations

import torch

from .triton_kernels import BLOCK_SIZE, guarded, tl, triton


if triton is not None:
    from .triton_shade import clip_row, vertex_at

    @triton.jit
    def _clip(vd_ptr, m_ptr, vi, mask):
        """Clip x, y, z, w of vertex ``vi`` under the view matrix at ``m_ptr``."""
        vx, vy, vz = vertex_at(vd_ptr, vi, mask)
        return (clip_row(m_ptr, 0, vx, vy, vz, mask), clip_row(m_ptr, 1, vx, vy, vz, mask),
                clip_row(m_ptr, 2, vx, vy, vz, mask), clip_row(m_ptr, 3, vx, vy, vz, mask))

    @triton.jit
    def _screen(vd_ptr, m_ptr, b, vi, width, height, mask):
        """Screen x, y of vertex ``vi`` in view ``b`` (``torch_antialias._face_screen``) and w > 0."""
        x, y, _, w = _clip(vd_ptr, m_ptr + b * 16, vi, mask)
        ws = tl.where(w > 0, w, 1.0)
        return (x / ws + 1.0) * (0.5 * width), (1.0 - y / ws) * (0.5 * height), w > 0

    @triton.jit
    def _crossing(sxa, sya, sxb, syb, fx, p0, VERTICAL: tl.constexpr):
        """Where edge (a, b) crosses the pair's segment (NaN: no straddle), and whether it is
        steep enough for the pair direction (``torch_antialias._crossings``)."""
        if VERTICAL:
            aa, ab, ca, cb = sya, syb, sxa, sxb
        else:
            aa, ab, ca, cb = sxa, sxb, sya, syb
        straddle = ((ca <= fx) & (fx < cb)) | ((cb <= fx) & (fx < ca))
        den = tl.where(straddle, cb - ca, 1.0)
        t = aa + (fx - ca) * (ab - aa) / den - p0
        steep = tl.abs(cb - ca) - tl.abs(ab - aa)
        if VERTICAL:
            ok = steep > 0
        else:
            ok = steep >= 0
        return tl.where(straddle, t, float("nan")), ok

    @triton.jit
    def _face_crossings(vd_ptr, f_ptr, m_ptr, b, face, fx, p0, width, height, mask,
                        VERTICAL: tl.constexpr):
        i0 = tl.load(f_ptr + face * 3, mask=mask, other=0)
        i1 = tl.load(f_ptr + face * 3 + 1, mask=mask, other=0)
        i2 = tl.load(f_ptr + face * 3 + 2, mask=mask, other=0)
        x0, y0, k0 = _screen(vd_ptr, m_ptr, b, i0, width, height, mask)
        x1, y1, k1 = _screen(vd_ptr, m_ptr, b, i1, width, height, mask)
        x2, y2, k2 = _screen(vd_ptr, m_ptr, b, i2, width, height, mask)
        t0, s0 = _crossing(x0, y0, x1, y1, fx, p0, VERTICAL)
        t1, s1 = _crossing(x1, y1, x2, y2, fx, p0, VERTICAL)
        t2, s2 = _crossing(x2, y2, x0, y0, fx, p0, VERTICAL)
        return t0, t1, t2, s0, s1, s2, k0 & k1 & k2, i0, i1, i2

    @triton.jit
    def _pick(t0, t1, t2, v0, v1, v2, near_a):
        """The edge with the first valid crossing away from the occluding pixel (the first of
        equal ones, as ``argmin``), its t, and whether any is valid (``torch_antialias._pick``)."""
        inf = float("inf")
        k0 = tl.where(v0, tl.where(near_a, t0, -t0), inf)
        k1 = tl.where(v1, tl.where(near_a, t1, -t1), inf)
        k2 = tl.where(v2, tl.where(near_a, t2, -t2), inf)
        e = tl.where(k1 < k0, 1, 0)
        best = tl.minimum(k0, k1)
        e = tl.where(k2 < best, 2, e)
        t = tl.where(e == 0, t0, tl.where(e == 1, t1, t2))
        return e, t, v0 | v1 | v2

    @triton.jit
    def _walk_kernel(vd_ptr, f_ptr, nbr_ptr, facing_ptr, m_ptr, b_ptr, cur_ptr, near_ptr,
                     walk_ptr, fixed_ptr, p0_ptr, code_ptr, n_pairs, n_faces, width, height,
                     MAX_WALK: tl.constexpr, VERTICAL: tl.constexpr, BLOCK: tl.constexpr):
        pid = tl.program_id(0)
        p = pid * BLOCK + tl.arange(0, BLOCK)
        live = p < n_pairs
        b = tl.load(b_ptr + p, mask=live, other=0)
        cur = tl.load(cur_ptr + p, mask=live, other=0)
        near_a = tl.load(near_ptr + p, mask=live, other=0) != 0
        walk = tl.load(walk_ptr + p, mask=live, other=0) != 0
        fx = tl.load(fixed_ptr + p, mask=live, other=0.0)
        p0 = tl.load(p0_ptr + p, mask=live, other=0.0)
        t0, t1, t2, s0, s1, s2, ok, i0, i1, i2 = _face_crossings(
            vd_ptr, f_ptr, m_ptr, b, cur, fx, p0, width, height, live, VERTICAL)
        e, t, alive = _pick(t0, t1, t2, (t0 >= 0) & (t0 <= 1), (t1 >= 0) & (t1 <= 1),
                            (t2 >= 0) & (t2 <= 1), near_a)
        steep = tl.where(e == 0, s0, tl.where(e == 1, s1, s2))
        active = live & alive & ok
        code = tl.full((BLOCK,), -1, tl.int64)
        fb = b * n_faces
        step = 0
        while (tl.max(active.to(tl.int32), axis=0) > 0) & (step < MAX_WALK):
            n = tl.load(nbr_ptr + cur * 3 + e, mask=active, other=-1)
            fc = tl.load(facing_ptr + fb + cur, mask=active, other=0)
            fn = tl.load(facing_ptr + fb + tl.maximum(n, 0), mask=active, other=0)
            sil = (n < 0) | (fn != fc)
            code = tl.where(active & sil & steep, cur * 3 + e, code)
            go = active & ~sil & walk
            e1 = tl.where(e == 2, 0, e + 1)
            ia = tl.load(f_ptr + cur * 3 + e, mask=go, other=0)
            ib = tl.load(f_ptr + cur * 3 + e1, mask=go, other=0)
            u0, u1, u2, r0, r1, r2, okn, j0, j1, j2 = _face_crossings(
                vd_ptr, f_ptr, m_ptr, b, n, fx, p0, width, height, go, VERTICAL)
            v0 = (u0 >= 0) & (u0 <= 1) & ~(((j0 == ia) & (j1 == ib)) | ((j0 == ib) & (j1 == ia))) \
                & tl.where(near_a, u0 >= t, u0 <= t)
            v1 = (u1 >= 0) & (u1 <= 1) & ~(((j1 == ia) & (j2 == ib)) | ((j1 == ib) & (j2 == ia))) \
                & tl.where(near_a, u1 >= t, u1 <= t)
            v2 = (u2 >= 0) & (u2 <= 1) & ~(((j2 == ia) & (j0 == ib)) | ((j2 == ib) & (j0 == ia))) \
                & tl.where(near_a, u2 >= t, u2 <= t)
            e2, tn, found = _pick(u0, u1, u2, v0, v1, v2, near_a)
            active = go & found & okn
            cur = tl.where(active, n, cur)
            e = tl.where(active, e2, e)
            t = tl.where(active, tn, t)
            steep = tl.where(e2 == 0, r0, tl.where(e2 == 1, r1, r2))
            step += 1
        tl.store(code_ptr + p, code, mask=live)


    @triton.jit
    def _projected(vd_ptr, m_ptr, vi, width, height, mask):
        """Screen x, y, clip z, w of vertex ``vi`` (``torch_raster.project``'s arithmetic)."""
        x, y, z, w = _clip(vd_ptr, m_ptr, vi, mask)
        return (x / w + 1.0) * (0.5 * width), (1.0 - y / w) * (0.5 * height), z, w

    @triton.jit
    def _facing_kernel(vd_ptr, f_ptr, m_ptr, out_ptr, n_items, n_faces, width, height,
                       BLOCK: tl.constexpr):
        item = tl.program_id(0).to(tl.int64) * BLOCK + tl.arange(0, BLOCK)
        live = item < n_items
        b, face = item // n_faces, item % n_faces
        mb = m_ptr + b * 16
        x0, y0, z0, w0 = _projected(vd_ptr, mb, tl.load(f_ptr + face * 3, mask=live, other=0),
                                    width, height, live)
        x1, y1, z1, w1 = _projected(vd_ptr, mb, tl.load(f_ptr + face * 3 + 1, mask=live, other=0),
                                    width, height, live)
        x2, y2, z2, w2 = _projected(vd_ptr, mb, tl.load(f_ptr + face * 3 + 2, mask=live, other=0),
                                    width, height, live)
        area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
        ok = (w0 > 0) & (w1 > 0) & (w2 > 0) & (z0 >= -w0) & (z1 >= -w1) & (z2 >= -w2)
        sign = tl.where(ok & (area > 0), 1, tl.where(ok & (area < 0), -1, 0))
        tl.store(out_ptr + item, sign.to(tl.int8), mask=live)


@guarded
def facing(vd: torch.Tensor, f: torch.Tensor, m64: torch.Tensor, width: int, height: int
           ) -> torch.Tensor:
    """``torch_antialias.face_facing`` in one kernel: (B, M) int8 sign of each face's screen
    area per view; ``vd`` (N, 3) float64, ``f`` (M, 3) int64, ``m64`` (B, 4, 4) float64."""
    out = torch.empty((len(m64), len(f)), dtype=torch.int8, device=vd.device)
    if out.numel():
        _facing_kernel[(triton.cdiv(out.numel(), BLOCK_SIZE),)](
            vd.contiguous(), f.contiguous(), m64.contiguous(), out, out.numel(), len(f), width,
            height, BLOCK=BLOCK_SIZE)
    return out


@guarded
def walk_codes(vd, f, nbr, facing, m64, b, cur, near_a, walk, fixed, p0, vertical: bool,
               width: int, height: int, max_walk: int) -> torch.Tensor:
    """``torch_antialias._walk`` in one kernel: (P,) silhouette edge codes (face * 3 + edge, -1)."""
    code = torch.empty(len(b), dtype=torch.int64, device=b.device)
    if len(b) == 0:
        return code
    grid = (triton.cdiv(len(b), BLOCK_SIZE),)
    _walk_kernel[grid](vd.contiguous(), f.contiguous(), nbr.contiguous(), facing.contiguous(),
                       m64.contiguous(), b.contiguous(), cur.contiguous(),
                       near_a.to(torch.int8), walk.to(torch.int8), fixed.contiguous(),
                       p0.contiguous(), code, len(b), f.shape[0], width, height,
                       MAX_WALK=max_walk, VERTICAL=vertical, BLOCK=BLOCK_SIZE)
    return code
