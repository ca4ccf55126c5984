"""Vertex → face lists of a mesh being decimated, one-rings and the link condition (numba).

``Lists`` layout: corner ``k = 3 f + c`` of face f is a node; ``nxt[k]`` links the nodes of
one vertex, from ``head[v]`` to ``tail[v]``. Node k always sits in the list of ``F[f, c]``
(a collapse renames the corners and moves the nodes along), so a vertex's faces are the live
faces of its nodes. Dead faces are dropped from a list when it is compacted.

``mark`` (one int per vertex) and ``tag`` (a 1-element counter) give O(1)-cleared vertex sets:
a vertex is in the current set when ``mark[v] == tag[0]``.
"""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel


@kernel(cache=True)
def build_lists(F, n_vertices):  # pragma: no cover - compiled
    """(head, tail, nxt) for the faces F (m, 3)."""
    m = F.shape[0]
    head = np.full(n_vertices, -1, np.int64)
    tail = np.full(n_vertices, -1, np.int64)
    nxt = np.full(3 * m, -1, np.int64)
    for k in range(3 * m):
        v = F[k // 3, k % 3]
        if head[v] < 0:
            head[v] = k
        else:
            nxt[tail[v]] = k
        tail[v] = k
    return head, tail, nxt


@kernel(cache=True)
def compact_list(v, head, tail, nxt, falive):  # pragma: no cover - compiled
    """Unlink the nodes of dead faces from v's list."""
    k = head[v]
    last = -1
    while k >= 0:
        n = nxt[k]
        if falive[k // 3]:
            if last < 0:
                head[v] = k
            else:
                nxt[last] = k
            last = k
        k = n
    if last < 0:
        head[v] = -1
    else:
        nxt[last] = -1
    tail[v] = last


@kernel(cache=True)
def new_tag(mark, tag):  # pragma: no cover - compiled
    tag[0] += 1
    return tag[0]


@kernel(cache=True)
def ring(v, F, head, nxt, falive, mark, tag, out):  # pragma: no cover - compiled
    """Distinct neighbours of v (its valence) into ``out``; returns their count (capped at
    len(out)). Leaves them marked with the current tag (and v too)."""
    t = new_tag(mark, tag)
    mark[v] = t
    n = 0
    k = head[v]
    while k >= 0:
        f = k // 3
        if falive[f]:
            for c in range(3):
                x = F[f, c]
                if mark[x] != t:
                    mark[x] = t
                    if n < out.shape[0]:
                        out[n] = x
                    n += 1
        k = nxt[k]
    return min(n, out.shape[0])


@kernel(cache=True)
def link_ok(u, v, F, head, nxt, falive, isb, mark, tag, buf):  # pragma: no cover - compiled
    """True when collapsing edge (u, v) keeps the surface a manifold of the same topology.

    The link condition with a dummy vertex joined to every boundary vertex (Dey et al.):
    the common neighbours of u and v must be exactly the edge's opposite vertices (plus the
    dummy on a boundary edge). This forbids pinching two boundary vertices through the
    interior and closing a three-edge hole. Besides, no opposite vertex may fall below
    valence 3 inside (2 on a boundary), which would fold two faces onto each other or
    leave a vertex without faces (a closed tetrahedron, a lone triangle), and the edge must
    have one or two faces.
    """
    n_uv = 0
    opp0 = -1
    opp1 = -1
    k = head[u]
    while k >= 0:
        f = k // 3
        if falive[f] and (F[f, 0] == v or F[f, 1] == v or F[f, 2] == v):
            n_uv += 1
            o = F[f, 0] + F[f, 1] + F[f, 2] - u - v
            if opp0 < 0:
                opp0 = o
            else:
                opp1 = o
        k = nxt[k]
    if n_uv == 0 or n_uv > 2:
        return False
    ring(u, F, head, nxt, falive, mark, tag, buf)
    tu = tag[0]
    # Count the common neighbours; mark them with a second tag so each counts once.
    t2 = new_tag(mark, tag)
    common = 0
    k = head[v]
    while k >= 0:
        f = k // 3
        if falive[f]:
            for c in range(3):
                x = F[f, c]
                if x != u and x != v and mark[x] == tu:
                    mark[x] = t2
                    common += 1
        k = nxt[k]
    if isb[u] and isb[v]:
        common += 1
    if common != n_uv + (1 if n_uv == 1 else 0):
        return False
    for o in (opp0, opp1):
        if o >= 0 and ring(o, F, head, nxt, falive, mark, tag, buf) < (3 if isb[o] else 4):
            return False
    return True
