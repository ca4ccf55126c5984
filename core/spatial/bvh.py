"""A bounding-volume hierarchy over triangles, built serially (compiled): median split of the
triangle centroids along the longest axis of their bounding box, down to leaves of at most
``leaf_size`` triangles; flat node arrays (float64 boxes, children stored as adjacent pairs).
The closest-point queries (:mod:`core.spatial.closest`) traverse it."""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel


@kernel(cache=True)
def _select(order, cent, axis, lo, hi, k):  # pragma: no cover - compiled
    """Reorder ``order[lo:hi]`` so ``order[k]`` holds the k-th smallest centroid along axis."""
    left, right = lo, hi - 1
    while right > left:
        pv = cent[order[(left + right) // 2], axis]
        i, j = left, right
        while i <= j:
            while cent[order[i], axis] < pv:
                i += 1
            while cent[order[j], axis] > pv:
                j -= 1
            if i <= j:
                t = order[i]
                order[i] = order[j]
                order[j] = t
                i += 1
                j -= 1
        if k <= j:
            right = j
        elif k >= i:
            left = i
        else:
            break


@kernel(cache=True)
def build_bvh(tri_lo, tri_hi, cent, leaf_size):  # pragma: no cover - compiled
    """Flat BVH: (node_lo, node_hi, child, start, count, order); ``count > 0`` marks a leaf,
    an inner node's children are ``child`` and ``child + 1``."""
    m = cent.shape[0]
    # a split leaves at least (leaf_size + 1) // 2 triangles on each side: at most that many
    # leaves, twice as many nodes (2 m + 1 for leaves of one: a third of the build's memory)
    cap = 2 * (m // max(1, (leaf_size + 1) // 2)) + 3
    node_lo = np.empty((cap, 3))
    node_hi = np.empty((cap, 3))
    child = np.full(cap, -1, np.int64)
    start = np.zeros(cap, np.int64)
    count = np.zeros(cap, np.int64)
    order = np.arange(m)
    st_node = np.empty(128, np.int64)
    st_lo = np.empty(128, np.int64)
    st_hi = np.empty(128, np.int64)
    st_node[0], st_lo[0], st_hi[0] = 0, 0, m
    top = 1
    n_nodes = 1
    while top > 0:
        top -= 1
        nd, lo, hi = st_node[top], st_lo[top], st_hi[top]
        blo = np.full(3, np.inf)
        bhi = np.full(3, -np.inf)
        clo = np.full(3, np.inf)
        chi = np.full(3, -np.inf)
        for ii in range(lo, hi):
            f = order[ii]
            for a in range(3):
                blo[a] = min(blo[a], tri_lo[f, a])
                bhi[a] = max(bhi[a], tri_hi[f, a])
                clo[a] = min(clo[a], cent[f, a])
                chi[a] = max(chi[a], cent[f, a])
        for a in range(3):  # element by element: a row assignment compiles a shape check
            node_lo[nd, a] = blo[a]      # whose error message costs 5 s of first-run compile
            node_hi[nd, a] = bhi[a]
        axis = np.int64(0)   # not a literal 0, which compiles _select once more
        ext = chi[0] - clo[0]
        for a in range(1, 3):
            if chi[a] - clo[a] > ext:
                axis, ext = a, chi[a] - clo[a]
        if hi - lo <= leaf_size or top + 2 > 128:
            start[nd], count[nd] = lo, hi - lo
            continue
        mid = (lo + hi) // 2
        if ext > 0.0:  # identical centroids: any halves will do
            _select(order, cent, axis, lo, hi, mid)
        c = n_nodes
        n_nodes += 2
        child[nd] = c
        # Push the right half first so the left is built next (depth-first, shallow stack).
        st_node[top], st_lo[top], st_hi[top] = c + 1, mid, hi
        st_node[top + 1], st_lo[top + 1], st_hi[top + 1] = c, lo, mid
        top += 2
    return (node_lo[:n_nodes].copy(), node_hi[:n_nodes].copy(), child[:n_nodes].copy(),
            start[:n_nodes].copy(), count[:n_nodes].copy(), order)


@kernel(cache=True)
def refit_bvh(A, B, C, child, start, count):  # pragma: no cover - compiled
    """Node boxes (node_lo, node_hi) of a tree built by :func:`build_bvh` over triangles whose
    corners moved: ``A``, ``B``, ``C`` (m, 3) the corners in the tree's leaf order. Children
    come after their parent, so one pass from the last node up suffices."""
    n = child.shape[0]
    node_lo = np.empty((n, 3))
    node_hi = np.empty((n, 3))
    for nd in range(n - 1, -1, -1):
        if count[nd] > 0:
            for a in range(3):
                lo, hi = np.inf, -np.inf
                for k in range(start[nd], start[nd] + count[nd]):
                    lo = min(lo, A[k, a], B[k, a], C[k, a])
                    hi = max(hi, A[k, a], B[k, a], C[k, a])
                node_lo[nd, a], node_hi[nd, a] = lo, hi
        else:
            c = child[nd]
            for a in range(3):
                node_lo[nd, a] = min(node_lo[c, a], node_lo[c + 1, a])
                node_hi[nd, a] = max(node_hi[c, a], node_hi[c + 1, a])
    return node_lo, node_hi
