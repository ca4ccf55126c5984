"""Numba analytic antialiasing (nvdiffrast's method) with an analytic backward.

Each pair of neighbouring pixels whose segment a silhouette edge crosses at t (measured from
a; the edges found by :mod:`core.render.silhouette`): the pixel whose box the edge cuts gets
the other pixel's colour blended in by the cut fraction: t >= 1/2 -> b += (t - 1/2) (a - b),
else a += (1/2 - t) (b - a). t depends on the edge's projected vertices, so the gradient
reaches the vertices on the outline. ``torch_antialias`` has the same rule.

The forward and the colour gradient are per-pixel gathers over the 4 pairs (no races); each
pair's vertex gradient is scattered once, into per-slot buffers as in ``shade``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..runtime.borrow import borrow
from ..runtime.jit import kernel
from .pixel import add_vertex_grad
from .silhouette import screen


@njit(inline="always")
def _edge_t(verts, faces, m, code, ra, ca, vertical, width, height):
    """t of the pair starting at (ra, ca) for edge ``code`` and the data its gradient needs."""
    occ, e = code // 3, code % 3
    ia, ib = faces[occ, e], faces[occ, (e + 1) % 3]
    sxa, sya, xa, ya, wa = screen(verts, m, ia, width, height)
    sxb, syb, xb, yb, wb = screen(verts, m, ib, width, height)
    if vertical:
        fixed, p0, ala, alb, aca, acb = ca + 0.5, ra + 0.5, sya, syb, sxa, sxb
    else:
        fixed, p0, ala, alb, aca, acb = ra + 0.5, ca + 0.5, sxa, sxb, sya, syb
    t = ala + (fixed - aca) * (alb - ala) / (acb - aca) - p0
    return t, ia, ib, fixed, ala, alb, aca, acb, xa, ya, wa, xb, yb, wb


@njit(inline="always")
def _pair_at(q, r, c, code_h, code_v, b, width, height):
    """The q-th pair around (r, c) (0 left, 1 right, 2 up, 3 down): (code, ra, ca, rb, cb,
    vertical, me_is_b); code -1 where the pair leaves the image."""
    if q == 0:
        return (code_h[b, r, c - 1] if c > 0 else -1), r, c - 1, r, c, False, True
    if q == 1:
        return code_h[b, r, c], r, c, r, c + 1, False, False
    if q == 2:
        return (code_v[b, r - 1, c] if r > 0 else -1), r - 1, c, r, c, True, True
    return code_v[b, r, c], r, c, r + 1, c, True, False


@njit(inline="always")
def _l1_row(img_row, target_row, sign_row):
    """Sum of |img - target| over one image row (W, C) in float64; sign_row <- the signs (int8).
    Flat and branch-free so that it vectorises (10x the per-pixel form with branches)."""
    a, t, s = img_row.ravel(), target_row.ravel(), sign_row.ravel()
    acc = 0.0
    for k in range(a.shape[0]):
        d = np.float64(a[k]) - np.float64(t[k])
        acc += abs(d)
        s[k] = np.int8(d > 0) - np.int8(d < 0)
    return acc


@kernel(nogil=True, error_model="numpy")
def antialias_forward(color, verts, faces, mvp, code_h, code_v, out, target, sign, rowsum, fuse_l1,
                      lo, hi):
    """out <- antialiased color. With ``fuse_l1`` instead sign <- sign(out - target) (int8) and
    rowsum[row] <- sum |out - target| over the row (the L1 loss without another image pass; the
    image only passes through a row buffer and ``out`` is not touched)."""
    color, verts, faces, mvp = borrow(color), borrow(verts), borrow(faces), borrow(mvp)
    code_h, code_v, out, target = borrow(code_h), borrow(code_v), borrow(out), borrow(target)
    sign, rowsum = borrow(sign), borrow(rowsum)
    nb, height, width, nc = color.shape
    for row in range(lo, hi):  # rows of all views: nb * height
        b, r = row // height, row % height
        m = mvp[b]
        o = np.empty((width, nc), color.dtype) if fuse_l1 else out[b, r]
        o.ravel()[:] = color[b, r].ravel()  # views: out and color are C-contiguous
        for c in range(width):
            for q in range(4):
                code, ra, ca, rb, cb, vertical, me_is_b = _pair_at(q, r, c, code_h, code_v, b, width, height)
                if code < 0:
                    continue
                t = _edge_t(verts, faces, m, code, ra, ca, vertical, width, height)[0]
                to_b = t >= 0.5
                if to_b != me_is_b:
                    continue
                alpha = t - 0.5 if to_b else 0.5 - t
                rs, cs = (ra, ca) if me_is_b else (rb, cb)
                for ch in range(nc):
                    o[c, ch] += alpha * (color[b, rs, cs, ch] - color[b, r, c, ch])
        if fuse_l1:
            rowsum[row] = _l1_row(o, target[b, r], sign[b, r])
    return 0


@kernel(nogil=True, error_model="numpy")
def l1_forward(img, target, sign, rowsum, lo, hi):
    """sign <- sign(img - target) (int8), rowsum[row] <- sum over the row of |img - target|."""
    nb, height, width = img.shape[:3]
    for row in range(lo, hi):  # nb * height
        b, r = row // height, row % height
        rowsum[row] = _l1_row(img[b, r], target[b, r], sign[b, r])
    return 0


@kernel(nogil=True, error_model="numpy")
def antialias_backward(color, verts, faces, mvp, code_h, code_v, gout, gscale, gcolor, gv, lo, hi):
    """gcolor (B, H, W, C) <- d/d color; gv (SLOTS, N, 3) <- per-slot parts of d/d verts.

    ``gout`` may be a float image or an int8 sign image (fused L1 loss); it is scaled by
    ``gscale``."""
    color, verts, faces, mvp = borrow(color), borrow(verts), borrow(faces), borrow(mvp)
    code_h, code_v, gout, gcolor, gv = borrow(code_h), borrow(code_v), borrow(gout), borrow(gcolor), borrow(gv)
    nb, height, width, nc = color.shape
    nslot = gv.shape[0]
    nrows = nb * height
    hw, hh = 0.5 * width, 0.5 * height
    for k in range(lo, hi):  # slots
        gvk = gv[k]
        gvk[:] = 0.0
        for row in range(k * nrows // nslot, (k + 1) * nrows // nslot):
            b, r = row // height, row % height
            m = mvp[b]
            gc, go = gcolor[b, r].ravel(), gout[b, r].ravel()
            for j in range(gc.shape[0]):  # flat, so that it vectorises; pairs adjust below
                gc[j] = gscale * go[j]
            for c in range(width):
                for q in range(4):
                    code, ra, ca, rb, cb, vertical, me_is_b = _pair_at(q, r, c, code_h, code_v, b, width, height)
                    if code < 0:
                        continue
                    t, ia, ib, fixed, ala, alb, aca, acb, xa, ya, wa, xb, yb, wb = _edge_t(
                        verts, faces, m, code, ra, ca, vertical, width, height)
                    to_b = t >= 0.5
                    alpha = t - 0.5 if to_b else 0.5 - t
                    rd, cd, rs, cs = (rb, cb, ra, ca) if to_b else (ra, ca, rb, cb)
                    if to_b == me_is_b:  # this pixel is the destination
                        for ch in range(nc):
                            gcolor[b, r, c, ch] -= alpha * gscale * gout[b, r, c, ch]
                    else:
                        for ch in range(nc):
                            gcolor[b, r, c, ch] += alpha * gscale * gout[b, rd, cd, ch]
                    if me_is_b:
                        continue  # the pair's vertex gradient is scattered once, by pixel a
                    gt = 0.0
                    for ch in range(nc):
                        gt += gscale * gout[b, rd, cd, ch] * (color[b, rs, cs, ch] - color[b, rd, cd, ch])
                    if not to_b:
                        gt = -gt
                    if gt == 0.0:
                        continue
                    kk = (fixed - aca) / (acb - aca)
                    slope = (alb - ala) / (acb - aca)
                    g_ala, g_alb = gt * (1.0 - kk), gt * kk
                    g_aca, g_acb = -gt * slope * (1.0 - kk), -gt * slope * kk
                    if vertical:
                        gsxa, gsya, gsxb, gsyb = g_aca, g_ala, g_acb, g_alb
                    else:
                        gsxa, gsya, gsxb, gsyb = g_ala, g_aca, g_alb, g_acb
                    add_vertex_grad(gvk, ia, m, gsxa * hw / wa, -gsya * hh / wa,
                                    (-gsxa * hw * xa + gsya * hh * ya) / (wa * wa))
                    add_vertex_grad(gvk, ib, m, gsxb * hw / wb, -gsyb * hh / wb,
                                    (-gsxb * hw * xb + gsyb * hh * yb) / (wb * wb))
    return 0
