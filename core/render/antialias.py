"""Numba analytic antialiasing (nvdiffrast's method) with an analytic backward.

For every horizontal and vertical pair of neighbouring pixels a, b with different face ids, the
face of the nearer pixel (background is farthest; ties to the smaller id) is tested for a
silhouette edge -- a boundary edge, or one whose neighbouring face faces the other way in this
view (or is degenerate / crosses the near plane) --
that crosses the segment between the two pixel centres at t in [0, 1] (t measured from a);
horizontal pairs only consider edges at least as steep as the diagonal, vertical pairs only
the flatter ones, as nvdiffrast does, so an edge's motion is counted once. With faces smaller
than a pixel the visible face's crossing edge is often interior (the silhouette lies inside a
sliver that covers no pixel centre); towards background or a clearly farther surface the
segment is then followed across neighbouring faces (up to ``MAX_WALK``) to the silhouette edge.
The
pixel whose box the edge cuts gets the other pixel's colour blended in by the cut fraction:
t >= 1/2 -> b += (t - 1/2) (a - b), else a += (1/2 - t) (b - a). t depends on the edge's projected
vertices, so the gradient reaches the vertices on the outline. ``torch_path`` has the same rule.

The silhouette-edge bits per pixel come from the rasteriser (``raster.silhouette_flags``).
Pass 1 finds each pair's edge once (code occ * 3 + e, -1 for none); the forward and the colour
gradient are per-pixel gathers over the 4 pairs (no races); each pair's vertex gradient is
scattered once, into per-slot buffers as in ``shade``.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..runtime.jit import kernel
from .prefetch import ahead
from .shade import add_vertex_grad, clip_xyw


@njit(inline="always")
def _screen(verts, m, i, width, height):
    x, y, w = clip_xyw(verts, m, i)
    return (x / w + 1.0) * (0.5 * width), (1.0 - y / w) * (0.5 * height), x, y, w


MAX_WALK = 64
"""Faces crossed at most, from the pixel's face to the silhouette (sub-pixel faces, see above)."""
WALK_DEPTH_RATIO = 1.01
"""Walk only towards background or a surface at least 1 % farther (an occlusion, not the same
surface)."""


@njit(inline="always")
def _face_screen(verts, faces, m, f, width, height):
    sx0, sy0, _, _, w0 = _screen(verts, m, faces[f, 0], width, height)
    sx1, sy1, _, _, w1 = _screen(verts, m, faces[f, 1], width, height)
    sx2, sy2, _, _, w2 = _screen(verts, m, faces[f, 2], width, height)
    ok = w0 > 0 and w1 > 0 and w2 > 0
    return sx0, sy0, sx1, sy1, sx2, sy2, ok


@njit(inline="always")
def _facing(sx0, sy0, sx1, sy1, sx2, sy2, ok):
    if not ok:
        return 0
    area = (sx1 - sx0) * (sy2 - sy0) - (sy1 - sy0) * (sx2 - sx0)
    return 1 if area > 0 else (-1 if area < 0 else 0)


@njit(inline="always")
def _crossing(sx0, sy0, sx1, sy1, sx2, sy2, e, vertical, fixed, p0):
    """t of edge e's crossing of the pair segment (NaN where it does not straddle), and whether
    the edge is steep enough for this pair direction."""
    if e == 0:
        xa, ya, xb, yb = sx0, sy0, sx1, sy1
    elif e == 1:
        xa, ya, xb, yb = sx1, sy1, sx2, sy2
    else:
        xa, ya, xb, yb = sx2, sy2, sx0, sy0
    if vertical:
        aa, ab, ca_, cb_ = ya, yb, xa, xb  # along y, across x
    else:
        aa, ab, ca_, cb_ = xa, xb, ya, yb
    if not ((ca_ <= fixed and fixed < cb_) or (cb_ <= fixed and fixed < ca_)):
        return np.nan, False
    steep = abs(cb_ - ca_) - abs(ab - aa)
    return aa + (fixed - ca_) * (ab - aa) / (cb_ - ca_) - p0, (steep > 0) if vertical else (steep >= 0)


@njit(inline="always")
def _pair_code(verts, faces, nbr, m, tb, db, fb, ra, ca, rb, cb, vertical, width, height):
    """occ * 3 + e of the silhouette edge crossing the pair a=(ra, ca), b=(rb, cb), or -1."""
    ida, idb = tb[ra, ca], tb[rb, cb]
    if ida == idb:
        return -1
    da, dd = db[ra, ca], db[rb, cb]
    near_a = idb < 0 or (ida >= 0 and (da < dd or (da == dd and ida < idb)))
    if near_a:
        cur, bits, walk = ida, fb[ra, ca], idb < 0 or dd > da * WALK_DEPTH_RATIO
    else:
        cur, bits, walk = idb, fb[rb, cb], ida < 0 or da > dd * WALK_DEPTH_RATIO
    if bits == 0 and not walk:
        return -1
    if vertical:
        fixed, p0 = ca + 0.5, ra + 0.5
    else:
        fixed, p0 = ra + 0.5, ca + 0.5
    return _edge_code(verts, faces, nbr, m, cur, bits, walk, near_a, vertical, fixed, p0,
                      width, height)


@njit
def _edge_code(verts, faces, nbr, m, cur, bits, walk, near_a, vertical, fixed, p0, width,
               height):
    """The rest of :func:`_pair_code` for the few pairs that may cross a silhouette: the exit
    edge of the occluding face and the walk to the silhouette. A call of its own (not
    inlined): compiled once instead of at both call sites of ``pair_codes``, which took most
    of the first run's compile time."""
    sx0, sy0, sx1, sy1, sx2, sy2, ok = _face_screen(verts, faces, m, cur, width, height)
    if not ok:
        return -1
    # the exit of the segment from the occluding pixel's face: first crossing going away from it
    e, t = -1, np.nan
    for k in range(3):
        tk = _crossing(sx0, sy0, sx1, sy1, sx2, sy2, k, vertical, fixed, p0)[0]
        if tk >= 0.0 and tk <= 1.0 and (e < 0 or (tk < t if near_a else tk > t)):
            e, t = k, tk
    if e < 0:
        return -1
    s_cur = 2
    nx0 = ny0 = nx1 = ny1 = nx2 = ny2 = 0.0
    nok = False
    for step in range(MAX_WALK):
        n = nbr[cur, e]
        projected = False
        if step == 0:
            sil = (bits >> e) & 1 == 1
        elif n < 0:
            sil = True
        else:
            if s_cur == 2:
                s_cur = _facing(sx0, sy0, sx1, sy1, sx2, sy2, ok)
            nx0, ny0, nx1, ny1, nx2, ny2, nok = _face_screen(verts, faces, m, n, width, height)
            projected = True
            sil = _facing(nx0, ny0, nx1, ny1, nx2, ny2, nok) != s_cur
        if sil:
            if _crossing(sx0, sy0, sx1, sy1, sx2, sy2, e, vertical, fixed, p0)[1]:
                return cur * 3 + e
            return -1  # the other pair direction handles this edge
        if not walk or n < 0:
            return -1
        # step into the neighbour (a front face covering no pixel centre) and find its exit
        ia, ib = faces[cur, e], faces[cur, (e + 1) % 3]
        if not projected:
            nx0, ny0, nx1, ny1, nx2, ny2, nok = _face_screen(verts, faces, m, n, width, height)
        sx0, sy0, sx1, sy1, sx2, sy2, ok = nx0, ny0, nx1, ny1, nx2, ny2, nok
        if not ok:
            return -1
        ne, nt = -1, np.nan
        for k in range(3):
            ka, kb = faces[n, k], faces[n, (k + 1) % 3]
            if (ka == ia and kb == ib) or (ka == ib and kb == ia):
                continue  # the edge we came through
            tk = _crossing(sx0, sy0, sx1, sy1, sx2, sy2, k, vertical, fixed, p0)[0]
            if tk >= 0.0 and tk <= 1.0 and (tk >= t if near_a else tk <= t) and \
                    (ne < 0 or (tk < nt if near_a else tk > nt)):
                ne, nt = k, tk
        if ne < 0:
            return -1
        cur, e, t, s_cur = n, ne, nt, 2
    return -1


@kernel(parallel=True)
def pair_codes(verts, faces, nbr, mvp, tri, depth, flags, code_h, code_v):
    """code_h[b, r, c]: pair (r, c)-(r, c + 1); code_v[b, r, c]: pair (r, c)-(r + 1, c)."""
    nb, height, width = tri.shape
    for row in prange(nb * height):
        b, r = row // height, row % height
        m = mvp[b]
        tb, db, fb = tri[b], depth[b], flags[b]
        for c in range(width):
            ahead(tb[r], faces, verts, c)
            if r + 1 < height:
                ahead(tb[r + 1], faces, verts, c)
            code_h[b, r, c] = -1 if c == width - 1 else _pair_code(
                verts, faces, nbr, m, tb, db, fb, r, c, r, c + 1, False, width, height)
            code_v[b, r, c] = -1 if r == height - 1 else _pair_code(
                verts, faces, nbr, m, tb, db, fb, r, c, r + 1, c, True, width, height)
    return 0


@njit(inline="always")
def _edge_t(verts, faces, m, code, ra, ca, vertical, width, height):
    """t of the pair starting at (ra, ca) for edge ``code`` and the data its gradient needs."""
    occ, e = code // 3, code % 3
    ia, ib = faces[occ, e], faces[occ, (e + 1) % 3]
    sxa, sya, xa, ya, wa = _screen(verts, m, ia, width, height)
    sxb, syb, xb, yb, wb = _screen(verts, m, ib, width, height)
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


@kernel(parallel=True)
def antialias_forward(color, verts, faces, mvp, code_h, code_v, out, target, sign, rowsum, fuse_l1):
    """out <- antialiased color. With ``fuse_l1`` instead sign <- sign(out - target) (int8) and
    rowsum[row] <- sum |out - target| over the row (the L1 loss without another image pass; the
    image only passes through a row buffer and ``out`` is not touched)."""
    nb, height, width, nc = color.shape
    for row in prange(nb * height):
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


@kernel(parallel=True)
def l1_forward(img, target, sign, rowsum):
    """sign <- sign(img - target) (int8), rowsum[row] <- sum over the row of |img - target|."""
    nb, height, width = img.shape[:3]
    for row in prange(nb * height):
        b, r = row // height, row % height
        rowsum[row] = _l1_row(img[b, r], target[b, r], sign[b, r])
    return 0


@kernel(parallel=True)
def antialias_backward(color, verts, faces, mvp, code_h, code_v, gout, gscale, gcolor, gv):
    """gcolor (B, H, W, C) <- d/d color; gv (SLOTS, N, 3) <- per-slot parts of d/d verts.

    ``gout`` may be a float image or an int8 sign image (fused L1 loss); it is scaled by
    ``gscale``."""
    nb, height, width, nc = color.shape
    nslot = gv.shape[0]
    nrows = nb * height
    hw, hh = 0.5 * width, 0.5 * height
    for k in prange(nslot):
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
