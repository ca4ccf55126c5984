"""Silhouette-edge bits per pixel: for each covered pixel, which edges of its face are
silhouettes in that view (no neighbour across the edge, or a neighbour facing the other
way). The rasteriser stores them as it goes (``raster``);
``numba_geometry.edge_flags_numba`` makes them for a raster that lacks them (one made by the
torch backend). The antialiasing reads them (``silhouette``)."""
from __future__ import annotations

from ..runtime.borrow import borrow
from ..runtime.jit import kernel
from .prefetch import FACE_AHEAD, prefetch
from .projection import project, screen_area


@kernel()
def silhouette_flags(nbr, fc, tb, fb):
    """Per covered pixel, bit e set where edge e of its face is a silhouette in this view: no
    neighbour across it, or the neighbour faces the other way (``fc``: per-face sign of the
    screen area, 0 for degenerate faces or faces crossing the near plane)."""
    height, width = tb.shape
    for r in range(height):
        for c in range(width):
            if c + FACE_AHEAD < width and tb[r, c + FACE_AHEAD] >= 0:
                prefetch(nbr, tb[r, c + FACE_AHEAD])
            f = tb[r, c]
            bits = 0
            if f >= 0:
                s = fc[f]
                for e in range(3):
                    n = nbr[f, e]
                    if n < 0 or fc[n] != s:
                        bits |= 1 << e
            fb[r, c] = bits
    return 0


@kernel()
def face_facing(faces, sc, fc):
    """fc[f] <- sign of the screen area of face f (0: degenerate or crossing the near plane)."""
    for f in range(faces.shape[0]):
        fc[f] = screen_area(sc, faces[f, 0], faces[f, 1], faces[f, 2])[2]
    return 0


@kernel(nogil=True, error_model="numpy")
def project_and_flag(verts, faces, nbr, mvp, width, height, scratch, facing, tri, flags, lo, hi):
    """Silhouette-edge bits for an existing raster (e.g. one made by the torch backend)."""
    verts, faces, nbr, mvp, scratch = borrow(verts), borrow(faces), borrow(nbr), borrow(mvp), borrow(scratch)
    facing, tri, flags = borrow(facing), borrow(tri), borrow(flags)
    nb = mvp.shape[0]
    nslot = scratch.shape[0]
    for slot in range(lo, hi):
        sc, fc = scratch[slot], facing[slot]
        for b in range(slot, nb, nslot):
            project(verts, mvp[b], width, height, sc)
            face_facing(faces, sc, fc)
            silhouette_flags(nbr, fc, tri[b], flags[b])
    return 0
