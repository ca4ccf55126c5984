"""Point location on a micro-mesh's topology: the micro-triangle and barycentrics of a point
given by its base face and barycentrics there."""
from __future__ import annotations

import numpy as np

from .level_grid import MAX_LEVEL, level_grid_view, level_triangles_view, snap_targets_view
from .topology import MicroTopology


def grid_cell(levels: np.ndarray | int, bary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The micro-triangle of a face's uniform lattice at ``levels`` (q,) (or one level)
    holding each of the points of barycentrics ``bary`` (q, 3) (w, u, v): ((q, 3) its corners
    as the face's u-major micro-vertex numbers, (q, 3) the points' barycentrics in it)."""
    S = (1 << np.asarray(levels, np.int64)) * np.ones(len(bary), np.int64)
    U, V = bary[:, 1] * S, bary[:, 2] * S
    iu = np.clip(np.floor(U).astype(np.int64), 0, S - 1)
    iv = np.clip(np.floor(V).astype(np.int64), 0, S - 1 - iu)
    fu, fv = U - iu, V - iv
    up = (fu + fv <= 1.0) | (iu + iv == S - 1)
    s2 = S + 2

    def um(u, v):
        return u * s2 - u * (u + 1) // 2 + v
    loc = np.where(up[:, None],
                   np.stack([um(iu, iv), um(iu + 1, iv), um(iu, iv + 1)], 1),
                   np.stack([um(iu + 1, iv), um(iu + 1, iv + 1), um(iu, iv + 1)], 1))
    w = np.where(up[:, None], np.stack([1 - fu - fv, fu, fv], 1),
                 np.stack([1 - fv, fu + fv - 1, 1 - fu], 1))
    return loc, w


def locate(topo: MicroTopology, faces: np.ndarray, bary: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Which micro-vertices and weights a surface point has: base faces (q,) and their
    barycentrics (q, 3) -> ((q, 3) micro-vertex indices of the micro-triangle holding each
    point, (q, 3) its barycentrics there), on the levels and edge flags of ``topo``
    (decimated edges' snapped micro-triangles included)."""
    L = topo.levels[faces]
    loc, w = grid_cell(L, bary)
    S = (1 << L).astype(np.int64)
    U, V = bary[:, 1] * S, bary[:, 2] * S

    # Faces with decimated edges: where the grid triangle touches a snapped vertex, search
    # the snapped micro-triangles of that strip instead.
    flags = topo.flags[faces].astype(np.int64)
    for level in range(1, MAX_LEVEL + 1):
        for fg in range(1, 8):
            grp = np.flatnonzero((L == level) & (flags == fg))
            if len(grp) == 0:
                continue
            tgt = snap_targets_view(level, fg)
            moved = tgt != np.arange(len(tgt))
            grp = grp[moved[loc[grp]].any(1)]
            if len(grp) == 0:
                continue
            lt = level_triangles_view(level)
            st = tgt[lt]
            cand = moved[lt].any(1) & (st[:, 0] != st[:, 1]) & (st[:, 1] != st[:, 2]) & \
                (st[:, 2] != st[:, 0])
            lt, st = lt[cand], st[cand]
            g = level_grid_view(level).astype(float)
            a, b, c = g[st[:, 0]], g[st[:, 1]], g[st[:, 2]]  # (c, 2) snapped corners
            p = np.stack([U[grp], V[grp]], 1)[:, None, :]    # (q, 1, 2)
            e1, e2, r = b - a, c - a, p - a
            det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
            l1 = (r[..., 0] * e2[:, 1] - r[..., 1] * e2[:, 0]) / det
            l2 = (e1[:, 0] * r[..., 1] - e1[:, 1] * r[..., 0]) / det
            l0 = 1 - l1 - l2
            best = np.minimum(np.minimum(l0, l1), l2).argmax(1)
            rows = np.arange(len(grp))
            loc[grp] = lt[best]
            w[grp] = np.stack([l0[rows, best], l1[rows, best], l2[rows, best]], 1)
    idx = topo.face_vertex_idx[topo.face_vertex_ptr[faces][:, None] + loc]
    return idx, w
