"""Numba z-buffer: visible face id and float32 view-space depth per pixel centre.

One buffer per view; thread slots (``parallel_for``, one piece per slot), each owning an
explicit scratch array of projected vertices and handling views slot, slot + T, ... (no
shared scratch, no races).
Coverage uses the same float64 arithmetic as ``torch_raster.rasterize_torch``: canonical edge
functions (from the lower to the higher vertex id, so a shared edge gives exactly opposite
values; E == 0 belongs to the face that walks the edge upwards in id) and the nearest float32
depth wins, ties to the smaller face id. Faces with a vertex behind the near plane are dropped.
Faces go in batches; batches of mostly sub-pixel faces first pick out, branch-free, the few
whose bounding box holds a pixel centre (see ``_raster_kernel``).
A post-pass per view stores each pixel's silhouette-edge bits for the antialiasing
(``edge_flags``).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..runtime.borrow import borrow
from ..runtime.jit import kernel
from .edge_flags import silhouette_flags
from .projection import project, screen_area


CHUNK = 1024
"""Faces per batch of the sparse path: few enough that their projected vertices are still in
cache when the batch's survivors are rasterised."""


@kernel()
def survivors(faces, sc, fc, start, stop, surv):
    """fc[f] <- facing sign of faces start..stop-1; surv[:n] <- those (ascending) that may cover
    a pixel centre: the bounding box spans a centre column and a centre row and the face faces
    some way (not degenerate, not crossing the near plane, finite). Returns n. Branch-free: it
    is the cheap path when most faces are smaller than a pixel."""
    n = 0
    for f in range(start, stop):
        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        x0, y0, x1, y1, x2, y2 = sc[i0, 0], sc[i0, 1], sc[i1, 0], sc[i1, 1], sc[i2, 0], sc[i2, 1]
        area, ok, s = screen_area(sc, i0, i1, i2)
        fc[f] = s
        spans_x = math.ceil(min(x0, x1, x2) - 0.5) <= math.floor(max(x0, x1, x2) - 0.5)
        spans_y = math.ceil(min(y0, y1, y2) - 0.5) <= math.floor(max(y0, y1, y2) - 0.5)
        surv[n] = f
        n += spans_x & spans_y & (s != 0) & (abs(area) < math.inf)
    return n


@njit(inline="always")
def rasterize_face(faces, sc, fc, f, width, height, tb, db, facing_known):
    """Depth-test face f at the pixel centres inside it (fc[f] <- its facing sign unless known).
    Returns whether its bounding box held a centre."""
    i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
    x0, y0, x1, y1, x2, y2 = sc[i0, 0], sc[i0, 1], sc[i1, 0], sc[i1, 1], sc[i2, 0], sc[i2, 1]
    area, ok, s = screen_area(sc, i0, i1, i2)
    if not facing_known:
        fc[f] = s
    # bounding box of pixel centres first: most small faces cover none
    c0 = max(math.ceil(min(x0, x1, x2) - 0.5), 0.0)
    c1 = min(math.floor(max(x0, x1, x2) - 0.5), width - 1.0)
    if not c0 <= c1:
        return False
    r0 = max(math.ceil(min(y0, y1, y2) - 0.5), 0.0)
    r1 = min(math.floor(max(y0, y1, y2) - 0.5), height - 1.0)
    if not r0 <= r1:
        return False
    if not ok or area == 0.0 or not math.isfinite(area):
        return False
    pos = area > 0
    iw0, iw1, iw2 = sc[i0, 2], sc[i1, 2], sc[i2, 2]
    # per edge once: endpoints in canonical order and the sign that restores the face's order
    t0, t1, t2 = i0 <= i1, i1 <= i2, i2 <= i0
    xl0, yl0, xh0, yh0 = (x0, y0, x1, y1) if t0 else (x1, y1, x0, y0)
    xl1, yl1, xh1, yh1 = (x1, y1, x2, y2) if t1 else (x2, y2, x1, y1)
    xl2, yl2, xh2, yh2 = (x2, y2, x0, y0) if t2 else (x0, y0, x2, y2)
    g0, g1, g2 = (1.0 if t0 else -1.0), (1.0 if t1 else -1.0), (1.0 if t2 else -1.0)
    for r in range(int(r0), int(r1) + 1):
        py = r + 0.5
        for c in range(int(c0), int(c1) + 1):
            px = c + 0.5
            e0 = g0 * ((xh0 - xl0) * (py - yl0) - (yh0 - yl0) * (px - xl0))
            s0 = e0 if pos else -e0
            if s0 < 0 or (s0 == 0 and not t0):
                continue
            e1 = g1 * ((xh1 - xl1) * (py - yl1) - (yh1 - yl1) * (px - xl1))
            s1 = e1 if pos else -e1
            if s1 < 0 or (s1 == 0 and not t1):
                continue
            e2 = g2 * ((xh2 - xl2) * (py - yl2) - (yh2 - yl2) * (px - xl2))
            s2 = e2 if pos else -e2
            if s2 < 0 or (s2 == 0 and not t2):
                continue
            inv_w = ((e1 * iw0 + e2 * iw1) + e0 * iw2) / area
            if not inv_w > 0:
                continue
            d = np.float32(1.0 / inv_w)
            if d < db[r, c]:
                db[r, c] = d
                tb[r, c] = f
    return True


@kernel(nogil=True, error_model="numpy")
def _raster_kernel(verts, faces, nbr, mvp, width, height, scratch, facing, surv, tri, depth, flags,
                   lo, hi):
    """Faces in batches of CHUNK. Where few faces of the last batch had a pixel centre in their
    bounding box (sub-pixel faces), a branch-free pass picks out the next batch's first; where
    most did, the next batch is rasterised directly (the pre-pass would only repeat their
    bounding boxes). Same result either way."""
    verts, faces, nbr, mvp, scratch = borrow(verts), borrow(faces), borrow(nbr), borrow(mvp), borrow(scratch)
    facing, surv, tri, depth, flags = borrow(facing), borrow(surv), borrow(tri), borrow(depth), borrow(flags)
    nb, nf = mvp.shape[0], faces.shape[0]
    nslot = scratch.shape[0]
    for slot in range(lo, hi):
        sc, fc, sv = scratch[slot], facing[slot], surv[slot]
        for b in range(slot, nb, nslot):
            project(verts, mvp[b], width, height, sc)
            tb, db = tri[b], depth[b]
            sparse = True
            for start in range(0, nf, CHUNK):
                stop = min(start + CHUNK, nf)
                if sparse:
                    n = survivors(faces, sc, fc, start, stop, sv)
                    for k in range(n):
                        rasterize_face(faces, sc, fc, sv[k], width, height, tb, db, True)
                else:
                    n = 0
                    for f in range(start, stop):
                        n += rasterize_face(faces, sc, fc, f, width, height, tb, db, False)
                sparse = 2 * n < stop - start
            silhouette_flags(nbr, fc, tb, flags[b])
    return 0
