"""Exact closest point on a triangle mesh: a BVH over the triangles, queried in parallel (numba).

Build (serial, compiled): median split of the triangle centroids along the longest axis of
their bounding box, down to leaves of at most ``LEAF_SIZE`` triangles; flat node arrays
(float64 boxes, children stored as adjacent pairs) and the triangles' corners copied in leaf
order so a leaf reads contiguous memory.

Query (``prange`` over blocks of points): depth-first traversal with an explicit stack per
block, the nearer child first, subtrees pruned by their box distance against the best squared
distance so far (initially ``max_distance²``), exact point–triangle closest points (Ericson's
Voronoi-region method) in float64. Degenerate (zero-area) triangles fall back to the nearest of
their three edges (flagged at build: squared sine of the angle at a corner ≤ 1e-20). Results do not depend on the thread count: each point's traversal is
sequential and deterministic, so ties between triangles always resolve the same way.
"""
from __future__ import annotations

import weakref

import numba
import numpy as np
from numba import prange

from .checks import as_points, per_point_distance
from .runtime.jit import kernel
from .mesh import TriMesh

LEAF_SIZE = 4
_STACK = 128          # > tree depth (≈ log2(m / LEAF_SIZE) + a few for duplicate centroids)
_BLOCK = 256          # points per parallel work item


class ClosestPointError(ValueError):
    """Bad input for closest-point queries (shapes, NaNs, negative distances, empty mesh)."""


# ------------------------------------------------------------------------------- build
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
def _build(tri_lo, tri_hi, cent, leaf_size):  # pragma: no cover - compiled
    """Flat BVH: (node_lo, node_hi, child, start, count, order); ``count > 0`` marks a leaf,
    an inner node's children are ``child`` and ``child + 1``."""
    m = cent.shape[0]
    cap = 2 * m + 1
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
        node_lo[nd] = blo
        node_hi[nd] = bhi
        axis = 0
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


# ------------------------------------------------------------------------------- query
@kernel(cache=True)
def _segment(px, py, pz, ax, ay, az, bx, by, bz):  # pragma: no cover - compiled
    """Closest point on segment ab: (x, y, z, squared distance)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    uu = ux * ux + uy * uy + uz * uz
    t = 0.0
    if uu > 0.0:
        t = ((px - ax) * ux + (py - ay) * uy + (pz - az) * uz) / uu
        t = min(1.0, max(0.0, t))
    x, y, z = ax + t * ux, ay + t * uy, az + t * uz
    dx, dy, dz = px - x, py - y, pz - z
    return x, y, z, dx * dx + dy * dy + dz * dz


@kernel(cache=True)
def _triangle(px, py, pz, A, B, C, flat, f):  # pragma: no cover - compiled
    """Closest point on triangle f (rows of A, B, C) to p: (x, y, z, squared distance)."""
    ax, ay, az = A[f, 0], A[f, 1], A[f, 2]
    bx, by, bz = B[f, 0], B[f, 1], B[f, 2]
    cx, cy, cz = C[f, 0], C[f, 1], C[f, 2]
    if flat[f]:  # (nearly) zero area: the region tests break down; it is its edges' union
        x, y, z, e = _segment(px, py, pz, ax, ay, az, bx, by, bz)
        x2, y2, z2, e2 = _segment(px, py, pz, bx, by, bz, cx, cy, cz)
        if e2 < e:
            x, y, z, e = x2, y2, z2, e2
        x2, y2, z2, e2 = _segment(px, py, pz, cx, cy, cz, ax, ay, az)
        if e2 < e:
            x, y, z, e = x2, y2, z2, e2
        return x, y, z, e
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    x, y, z = ax, ay, az
    if d1 <= 0.0 and d2 <= 0.0:                                   # vertex a
        x, y, z = ax, ay, az
    else:
        bpx, bpy, bpz = px - bx, py - by, pz - bz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        cpx, cpy, cpz = px - cx, py - cy, pz - cz
        d5 = abx * cpx + aby * cpy + abz * cpz
        d6 = acx * cpx + acy * cpy + acz * cpz
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:                                # vertex b
            x, y, z = bx, by, bz
        elif d6 >= 0.0 and d5 <= d6:                              # vertex c
            x, y, z = cx, cy, cz
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:               # edge ab
            den = d1 - d3
            v = d1 / den if den > 0.0 else 0.0
            x, y, z = ax + v * abx, ay + v * aby, az + v * abz
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:               # edge ac
            den = d2 - d6
            w = d2 / den if den > 0.0 else 0.0
            x, y, z = ax + w * acx, ay + w * acy, az + w * acz
        elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:    # edge bc
            den = (d4 - d3) + (d5 - d6)
            w = (d4 - d3) / den if den > 0.0 else 0.0
            x, y, z = bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz)
        else:                                                     # face interior
            den = va + vb + vc
            v = vb / den
            w = vc / den
            x, y, z = ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w
    dx, dy, dz = px - x, py - y, pz - z
    return x, y, z, dx * dx + dy * dy + dz * dz


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
        d0 = _box_d2(px, py, pz, lo, hi, 0)
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
                    x, y, z, d2 = _triangle(px, py, pz, A, B, C, flat, k)
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


@kernel(cache=True, parallel=True)
def _query(pts, md2, lo, hi, child, start, count, A, B, C, flat, fid, block,
           out_p, out_f, out_d2):  # pragma: no cover - compiled
    n = pts.shape[0]
    nb = (n + block - 1) // block
    for b in prange(nb):
        _query_block(b * block, min(n, (b + 1) * block), pts, md2, lo, hi, child, start, count,
                     A, B, C, flat, fid, out_p, out_f, out_d2)


# ------------------------------------------------------------------------------- API
class ClosestPointIndex:
    """BVH over a triangle mesh for exact closest-point queries; build once, query often.

    ``vertices`` (n, 3) float, ``faces`` (m, 3) int. Degenerate triangles are allowed (they act
    as segments or points). Queries run on numba's thread pool (``core.runtime.threads.set_threads``).
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ClosestPointError(f"vertices must be (n, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
            raise ClosestPointError(f"faces must be (m, 3) integers, got {f.shape} {f.dtype}")
        if len(f) == 0:
            raise ClosestPointError("mesh has no faces")
        if f.min() < 0 or f.max() >= len(v):
            raise ClosestPointError("face index out of range")
        if not np.isfinite(v).all():
            raise ClosestPointError("vertices contain NaN or infinity")
        tri = v[f.astype(np.int64)]                                  # (m, 3, 3)
        lo, hi, child, start, count, order = _build(
            np.ascontiguousarray(tri.min(axis=1)), np.ascontiguousarray(tri.max(axis=1)),
            np.ascontiguousarray(tri.mean(axis=1)), LEAF_SIZE)
        t = tri[order]
        self._A = np.ascontiguousarray(t[:, 0])
        self._B = np.ascontiguousarray(t[:, 1])
        self._C = np.ascontiguousarray(t[:, 2])
        self._fid = order.astype(np.int64)
        ab, ac = self._B - self._A, self._C - self._A
        n2 = np.einsum("ij,ij->i", *(2 * [np.cross(ab, ac)]))
        scale = np.einsum("ij,ij->i", ab, ab) * np.einsum("ij,ij->i", ac, ac)
        self._flat = n2 <= 1e-20 * scale  # sin² of the angle at a: collinear or repeated corners
        self._nodes = (lo, hi, child, start, count)
        self.n_faces = len(f)

    @property
    def n_nodes(self) -> int:
        return len(self._nodes[0])

    def query(self, points: np.ndarray, max_distance: float | np.ndarray = np.inf, *,
              threads: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(closest (n, 3), face (n,), distance (n,)) for each point.

        ``max_distance`` (scalar or (n,)) bounds the search: where no triangle lies within it the
        point gets distance ``inf``, face −1 and closest NaN. Smaller bounds query faster.
        ``threads``: numba threads for this call only (default: the pool's setting).
        """
        q = as_points(points, "points", ClosestPointError)
        n = len(q)
        md = per_point_distance(max_distance, n, ClosestPointError)
        out_p = np.empty((n, 3))
        out_f = np.empty(n, np.int64)
        out_d2 = np.empty(n)
        if n:
            old = numba.get_num_threads()
            if threads:  # numba's thread count is thread-local: restoring it is safe
                numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
            try:
                _query(np.ascontiguousarray(q), md * md * (1 + 1e-14), *self._nodes, self._A, self._B, self._C,
                       self._flat, self._fid, _BLOCK, out_p, out_f, out_d2)
            finally:
                numba.set_num_threads(old)
        dist = np.sqrt(out_d2)
        out = dist > md  # searched with a hair more than md²: keep the bound exact in distance
        if out.any():
            dist[out], out_f[out], out_p[out] = np.inf, -1, np.nan
        return out_p, out_f, dist


_CACHE: "weakref.WeakKeyDictionary[TriMesh, ClosestPointIndex]" = weakref.WeakKeyDictionary()


def closest_point_index(mesh: TriMesh) -> ClosestPointIndex:
    """The (cached) index of ``mesh``; a TriMesh is immutable, so it is built once per mesh."""
    idx = _CACHE.get(mesh)
    if idx is None:
        idx = _CACHE[mesh] = ClosestPointIndex(mesh.vertices, mesh.faces)
    return idx
