"""Fused CUDA kernels (Triton) for the two loops of the torch path that plain torch runs as
thousands of small kernels: the rasteriser's per-(view, face) pixel loop and the antialiasing
walk across sub-pixel faces. Same rules and float64 arithmetic as ``torch_path`` (which stays
the reference: tests compare the two); only their own atomics touch shared memory, and an
atomic minimum is order-independent.

Imported only where Triton is (``available()``); every function takes and returns torch
tensors on one CUDA device.
"""
from __future__ import annotations

import functools
import warnings

import torch

try:
    import triton
    import triton.language as tl
except ImportError:  # pragma: no cover - CPU-only installs
    triton = None

_BLOCK = 128
failure: str | None = None
"""Why a kernel failed to compile or launch (then none is used again in this process)."""


def available(device: torch.device) -> bool:
    """Whether the fused kernels can run on ``device`` (CUDA, Triton importable, none failed)."""
    return triton is not None and device.type == "cuda" and failure is None


def _guarded(fn):
    """A kernel wrapper that returns None instead of raising where Triton fails (a compiler or
    driver it cannot use): the caller then runs the plain torch path, with a warning once."""
    @functools.wraps(fn)
    def run(*args, **kwargs):
        global failure
        try:
            return fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - any compiler or driver error
            failure = f"{type(exc).__name__}: {exc}"
            warnings.warn(f"the fused CUDA kernels cannot run here ({failure}); the renderer "
                          "uses its plain torch path", RuntimeWarning, stacklevel=3)
            return None
    return run


if triton is not None:
    @triton.jit
    def _raster_kernel(f_ptr, sx_ptr, sy_ptr, w_ptr, z_ptr, keys_ptr, n_items, n_faces, n_verts,
                       view0, width, height, BLOCK: tl.constexpr):
        pid = tl.program_id(0)
        item = pid * BLOCK + tl.arange(0, BLOCK)
        live = item < n_items
        g = item // n_faces               # view within the group
        face = item % n_faces
        i0 = tl.load(f_ptr + face * 3, mask=live, other=0)
        i1 = tl.load(f_ptr + face * 3 + 1, mask=live, other=0)
        i2 = tl.load(f_ptr + face * 3 + 2, mask=live, other=0)
        o = g * n_verts
        x0 = tl.load(sx_ptr + o + i0, mask=live, other=0.0)
        x1 = tl.load(sx_ptr + o + i1, mask=live, other=0.0)
        x2 = tl.load(sx_ptr + o + i2, mask=live, other=0.0)
        y0 = tl.load(sy_ptr + o + i0, mask=live, other=0.0)
        y1 = tl.load(sy_ptr + o + i1, mask=live, other=0.0)
        y2 = tl.load(sy_ptr + o + i2, mask=live, other=0.0)
        w0 = tl.load(w_ptr + o + i0, mask=live, other=0.0)
        w1 = tl.load(w_ptr + o + i1, mask=live, other=0.0)
        w2 = tl.load(w_ptr + o + i2, mask=live, other=0.0)
        z0 = tl.load(z_ptr + o + i0, mask=live, other=0.0)
        z1 = tl.load(z_ptr + o + i1, mask=live, other=0.0)
        z2 = tl.load(z_ptr + o + i2, mask=live, other=0.0)
        ok = live & (w0 > 0) & (w1 > 0) & (w2 > 0) & (z0 >= -w0) & (z1 >= -w1) & (z2 >= -w2)
        area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
        ok = ok & (area != 0) & (area == area) & (tl.abs(area) < float("inf"))
        fw = width * 1.0
        fh = height * 1.0
        c0 = tl.minimum(tl.maximum(tl.ceil(tl.minimum(tl.minimum(x0, x1), x2) - 0.5), 0.0), fw)
        c1 = tl.minimum(tl.maximum(tl.floor(tl.maximum(tl.maximum(x0, x1), x2) - 0.5), -1.0), fw - 1)
        r0 = tl.minimum(tl.maximum(tl.ceil(tl.minimum(tl.minimum(y0, y1), y2) - 0.5), 0.0), fh)
        r1 = tl.minimum(tl.maximum(tl.floor(tl.maximum(tl.maximum(y0, y1), y2) - 0.5), -1.0), fh - 1)
        nx = tl.maximum(c1 - c0 + 1, 0.0).to(tl.int32)
        ny = tl.maximum(r1 - r0 + 1, 0.0).to(tl.int32)
        count = tl.where(ok, nx * ny, 0)
        sa = tl.where(area > 0, 1.0, -1.0)
        # canonical edges: from the lower vertex id to the higher (exactly opposite values on
        # the two faces of an edge); s: edge sign with the face's orientation; t: owns E == 0
        sw0 = i0 > i1
        lx0 = tl.where(sw0, x1, x0)
        ly0 = tl.where(sw0, y1, y0)
        dx0 = tl.where(sw0, x0, x1) - lx0
        dy0 = tl.where(sw0, y0, y1) - ly0
        sw1 = i1 > i2
        lx1 = tl.where(sw1, x2, x1)
        ly1 = tl.where(sw1, y2, y1)
        dx1 = tl.where(sw1, x1, x2) - lx1
        dy1 = tl.where(sw1, y1, y2) - ly1
        sw2 = i2 > i0
        lx2 = tl.where(sw2, x0, x2)
        ly2 = tl.where(sw2, y0, y2)
        dx2 = tl.where(sw2, x2, x0) - lx2
        dy2 = tl.where(sw2, y2, y0) - ly2
        g0 = tl.where(sw0, -1.0, 1.0)
        g1 = tl.where(sw1, -1.0, 1.0)
        g2 = tl.where(sw2, -1.0, 1.0)
        wq0 = g1 * (1.0 / w0)
        wq1 = g2 * (1.0 / w1)
        wq2 = g0 * (1.0 / w2)
        s0 = g0 * sa
        s1 = g1 * sa
        s2 = g2 * sa
        c0i = c0.to(tl.int32)
        r0i = r0.to(tl.int32)
        nxs = tl.maximum(nx, 1)
        hw = width * height
        pix0 = (view0 + g).to(tl.int64) * hw
        n_max = tl.max(count, axis=0)
        k = 0
        while k < n_max:
            run = k < count
            col = c0i + k % nxs
            row = r0i + k // nxs
            px = col.to(tl.float64) + 0.5
            py = row.to(tl.float64) + 0.5
            e0 = dx0 * (py - ly0) - dy0 * (px - lx0)
            e1 = dx1 * (py - ly1) - dy1 * (px - lx1)
            e2 = dx2 * (py - ly2) - dy2 * (px - lx2)
            es0 = e0 * s0
            es1 = e1 * s1
            es2 = e2 * s2
            ins = ((es0 > 0) | ((es0 == 0) & ~sw0)) & ((es1 > 0) | ((es1 == 0) & ~sw1)) \
                & ((es2 > 0) | ((es2 == 0) & ~sw2))
            inv_w = ((e1 * wq0 + e2 * wq1) + e0 * wq2) / area
            ins = ins & run & (inv_w > 0)
            d32 = (1.0 / inv_w).to(tl.float32)
            key = (d32.to(tl.int32, bitcast=True).to(tl.int64) << 32) | face.to(tl.int64)
            tl.atomic_min(keys_ptr + pix0 + row * width + col, key, mask=ins)
            k += 1


@_guarded
def rasterize_keys(keys: torch.Tensor, f: torch.Tensor, sx, sy, w, z, view0: int, width: int,
                   height: int) -> bool:
    """Fold the (float32 depth bits << 32 | face) keys of every covered pixel of the views
    ``view0 .. view0 + G`` into ``keys`` (B * H * W,) by atomic minimum; ``sx, sy, w, z`` (G, N)
    float64 screen coordinates of those views, ``f`` (M, 3) int64 faces. True when done."""
    g, n = sx.shape
    items = g * len(f)
    if items == 0:
        return True
    grid = (triton.cdiv(items, _BLOCK),)
    _raster_kernel[grid](f.contiguous(), sx.contiguous(), sy.contiguous(), w.contiguous(),
                         z.contiguous(), keys, items, len(f), n, view0, width, height,
                         BLOCK=_BLOCK)
    return True


if triton is not None:
    @triton.jit
    def _screen(vd_ptr, m_ptr, b, vi, width, height, mask):
        """Screen x, y of vertex ``vi`` in view ``b`` (``torch_path._face_screen``) and w > 0."""
        vx = tl.load(vd_ptr + vi * 3, mask=mask, other=0.0)
        vy = tl.load(vd_ptr + vi * 3 + 1, mask=mask, other=0.0)
        vz = tl.load(vd_ptr + vi * 3 + 2, mask=mask, other=0.0)
        mb = m_ptr + b * 16
        x = ((tl.load(mb, mask=mask, other=0.0) * vx + tl.load(mb + 1, mask=mask, other=0.0) * vy)
             + tl.load(mb + 2, mask=mask, other=0.0) * vz) + tl.load(mb + 3, mask=mask, other=0.0)
        y = ((tl.load(mb + 4, mask=mask, other=0.0) * vx + tl.load(mb + 5, mask=mask, other=0.0) * vy)
             + tl.load(mb + 6, mask=mask, other=0.0) * vz) + tl.load(mb + 7, mask=mask, other=0.0)
        w = ((tl.load(mb + 12, mask=mask, other=0.0) * vx + tl.load(mb + 13, mask=mask, other=0.0) * vy)
             + tl.load(mb + 14, mask=mask, other=0.0) * vz) + tl.load(mb + 15, mask=mask, other=1.0)
        ws = tl.where(w > 0, w, 1.0)
        return (x / ws + 1.0) * (0.5 * width), (1.0 - y / ws) * (0.5 * height), w > 0

    @triton.jit
    def _crossing(sxa, sya, sxb, syb, fx, p0, VERTICAL: tl.constexpr):
        """Where edge (a, b) crosses the pair's segment (NaN: no straddle), and whether it is
        steep enough for the pair direction (``torch_path._crossings``)."""
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
        equal ones, as ``argmin``), its t, and whether any is valid (``torch_path._pick``)."""
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


@_guarded
def walk_codes(vd, f, nbr, facing, m64, b, cur, near_a, walk, fixed, p0, vertical: bool,
               width: int, height: int, max_walk: int) -> torch.Tensor:
    """``torch_path._walk`` in one kernel: (P,) silhouette edge codes (face * 3 + edge, -1)."""
    code = torch.empty(len(b), dtype=torch.int64, device=b.device)
    if len(b) == 0:
        return code
    grid = (triton.cdiv(len(b), _BLOCK),)
    _walk_kernel[grid](vd.contiguous(), f.contiguous(), nbr.contiguous(), facing.contiguous(),
                       m64.contiguous(), b.contiguous(), cur.contiguous(),
                       near_a.to(torch.int8), walk.to(torch.int8), fixed.contiguous(),
                       p0.contiguous(), code, len(b), f.shape[0], width, height,
                       MAX_WALK=max_walk, VERTICAL=vertical, BLOCK=_BLOCK)
    return code
