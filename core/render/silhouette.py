"""Which silhouette edge each pair of neighbouring pixels crosses (pass 1 of the antialiasing,
:mod:`core.render.antialias`), compiled.

For every horizontal and vertical pair of neighbouring pixels a, b with different face ids, the
face of the nearer pixel (background is farthest; ties to the smaller id) is tested for a
silhouette edge -- a boundary edge, or one whose neighbouring face faces the other way in this
view (or is degenerate / crosses the near plane) -- that crosses the segment between the two
pixel centres at t in [0, 1] (t measured from a); horizontal pairs only consider edges at least
as steep as the diagonal, vertical pairs only the flatter ones, as nvdiffrast does, so an
edge's motion is counted once. With faces smaller than a pixel the visible face's crossing edge
is often interior (the silhouette lies inside a sliver that covers no pixel centre); towards
background or a clearly farther surface the segment is then followed across neighbouring faces
(up to ``MAX_WALK``) to the silhouette edge. ``torch_antialias`` has the same rule.

The silhouette-edge bits per pixel come from the rasteriser (``edge_flags.silhouette_flags``);
each pair's edge is found once (code occ * 3 + e, -1 for none).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..runtime.borrow import borrow
from ..runtime.jit import kernel
from .pixel import clip_xyw
from .prefetch import ahead


@njit(inline="always")
def screen(verts, m, i, width, height):
    x, y, w = clip_xyw(verts, m, i)
    return (x / w + 1.0) * (0.5 * width), (1.0 - y / w) * (0.5 * height), x, y, w


MAX_WALK = 64
"""Faces crossed at most, from the pixel's face to the silhouette (sub-pixel faces, see above)."""
WALK_DEPTH_RATIO = 1.01
"""Walk only towards background or a surface at least 1 % farther (an occlusion, not the same
surface)."""


@njit(inline="always")
def _face_screen(verts, faces, m, f, width, height):
    sx0, sy0, _, _, w0 = screen(verts, m, faces[f, 0], width, height)
    sx1, sy1, _, _, w1 = screen(verts, m, faces[f, 1], width, height)
    sx2, sy2, _, _, w2 = screen(verts, m, faces[f, 2], width, height)
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
    # np.bool_: a plain bool argument, not the literal True / False of the caller (which
    # would compile _edge_code twice, 2 s each on a fresh cache, for no speed)
    return _edge_code(verts, faces, nbr, m, cur, bits, walk, near_a, np.bool_(vertical), fixed,
                      p0, width, height)


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


@kernel(nogil=True, error_model="numpy")
def pair_codes(verts, faces, nbr, mvp, tri, depth, flags, code_h, code_v, lo, hi):
    """code_h[b, r, c]: pair (r, c)-(r, c + 1); code_v[b, r, c]: pair (r, c)-(r + 1, c)."""
    verts, faces, nbr, mvp, tri = borrow(verts), borrow(faces), borrow(nbr), borrow(mvp), borrow(tri)
    depth, flags, code_h, code_v = borrow(depth), borrow(flags), borrow(code_h), borrow(code_v)
    nb, height, width = tri.shape
    for row in range(lo, hi):  # rows of all views: nb * height
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
