"""Nearest triangles in a BVH (:mod:`core.spatial.bvh`), in parallel (blocks of points, on
``runtime.threads.parallel_for``): depth-first traversal with an explicit stack per block,
the nearer child first, subtrees pruned by their box distance against the best squared
distance so far (initially the caller's bound), exact point–triangle closest points
(:mod:`core.spatial.point_triangle`).
Results do not depend on the thread count: each point's traversal is sequential and
deterministic, so ties between triangles always resolve the same way. The index around it:
:class:`core.spatial.closest.ClosestPointIndex`.
"""
from __future__ import annotations

import numpy as np

from .point_triangle import closest_on_triangle
from ..runtime.borrow import borrow
from ..runtime.jit import kernel

_STACK = 128          # > tree depth (≈ log2(m / leaf size) + a few for duplicate centroids)


@kernel(cache=True)
def _box_d2(px, py, pz, lo, hi, nd):  # pragma: no cover - compiled
    d = 0.0
    t = lo[nd, 0] - px
    if t > 0.0:
        d += t * t
    t = px - hi[nd, 0]
    if t > 0.0:
        d += t * t
    t = lo[nd, 1] - py
    if t > 0.0:
        d += t * t
    t = py - hi[nd, 1]
    if t > 0.0:
        d += t * t
    t = lo[nd, 2] - pz
    if t > 0.0:
        d += t * t
    t = pz - hi[nd, 2]
    if t > 0.0:
        d += t * t
    return d


@kernel(cache=True)
def _query_block(s0, s1, pts, md2, lo, hi, child, start, count, A, B, C, flat, fid,
                 out_p, out_f, out_d2):  # pragma: no cover - compiled
    """Points s0..s1-1, sequentially, with one explicit stack (allocated here, per block)."""
    st = np.empty(_STACK, np.int64)
    sd = np.empty(_STACK)
    for i in range(s0, s1):
        px, py, pz = pts[i, 0], pts[i, 1], pts[i, 2]
        best = md2[i]
        bf = -1
        bx, by, bz = np.nan, np.nan, np.nan
        top = 0
        d0 = _box_d2(px, py, pz, lo, hi, np.int64(0))   # not a literal (one compile less)
        if d0 <= best:
            st[0], sd[0] = 0, d0
            top = 1
        while top > 0:
            top -= 1
            nd = st[top]
            if sd[top] > best:
                continue
            cnt = count[nd]
            if cnt > 0:
                for k in range(start[nd], start[nd] + cnt):
                    x, y, z, d2 = closest_on_triangle(px, py, pz, A, B, C, flat, k)
                    if d2 < best or (bf < 0 and d2 <= best):
                        best, bf, bx, by, bz = d2, k, x, y, z
            else:
                c = child[nd]
                dl = _box_d2(px, py, pz, lo, hi, c)
                dr = _box_d2(px, py, pz, lo, hi, c + 1)
                if dl <= dr:   # push the farther one first: the nearer is popped next
                    if dr <= best:
                        st[top], sd[top] = c + 1, dr
                        top += 1
                    if dl <= best:
                        st[top], sd[top] = c, dl
                        top += 1
                else:
                    if dl <= best:
                        st[top], sd[top] = c, dl
                        top += 1
                    if dr <= best:
                        st[top], sd[top] = c + 1, dr
                        top += 1
        out_p[i, 0], out_p[i, 1], out_p[i, 2] = bx, by, bz
        out_f[i] = fid[bf] if bf >= 0 else -1
        out_d2[i] = best if bf >= 0 else np.inf


@kernel(cache=True, nogil=True, error_model="numpy")
def query_nearest(pts, md2, lo, hi, child, start, count, A, B, C, flat, fid, block,
                  out_p, out_f, out_d2, b0, b1):  # pragma: no cover - compiled
    """For each point of ``pts`` (n, 3), the nearest triangle within ``sqrt(md2)``: its
    closest point into ``out_p`` (n, 3), its face (``fid`` of its leaf slot) into ``out_f``
    (n,) and the squared distance into ``out_d2`` (n,); face -1, NaN and inf where none lies
    within. ``lo``..``count``: the tree (:func:`core.spatial.bvh.build_bvh`); ``A``, ``B``, ``C``
    (m, 3) and ``flat`` (m,): the triangles' corners in leaf order and which are degenerate;
    ``block`` points per work item; blocks ``b0``..``b1 - 1`` of them."""
    pts, md2, lo, hi, child = borrow(pts), borrow(md2), borrow(lo), borrow(hi), borrow(child)
    start, count, A, B, C, flat = borrow(start), borrow(count), borrow(A), borrow(B), borrow(C), borrow(flat)
    fid, out_p, out_f, out_d2 = borrow(fid), borrow(out_p), borrow(out_f), borrow(out_d2)
    n = pts.shape[0]
    for b in range(b0, b1):  # blocks of points: ceil(n / block)
        _query_block(b * block, min(n, (b + 1) * block), pts, md2, lo, hi, child, start, count,
                     A, B, C, flat, fid, out_p, out_f, out_d2)
