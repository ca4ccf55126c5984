"""Exact closest point on a triangle mesh: a BVH over the triangles, queried in parallel (numba).

Build: :mod:`core.bvh` (leaves of at most ``LEAF_SIZE`` triangles), then the triangles'
corners copied in leaf order so a leaf reads contiguous memory.

Query (``prange`` over blocks of points): depth-first traversal with an explicit stack per
block, the nearer child first, subtrees pruned by their box distance against the best squared
distance so far (initially ``max_distance²``), exact point–triangle closest points
(:mod:`core.point_triangle`). Degenerate (zero-area) triangles fall back to the nearest of
their three edges (flagged at build: squared sine of the angle at a corner ≤ 1e-20). Results
do not depend on the thread count: each point's traversal is sequential and deterministic, so
ties between triangles always resolve the same way.
"""
from __future__ import annotations

import weakref

import numba
import numpy as np
from numba import prange

from .bvh import build_bvh, refit_bvh
from .checks import as_points, per_point_distance
from .runtime.jit import kernel
from .mesh import TriMesh
from .point_triangle import closest_on_triangle

LEAF_SIZE = 4
_STACK = 128          # > tree depth (≈ log2(m / LEAF_SIZE) + a few for duplicate centroids)
_BLOCK = 256          # points per parallel work item


class ClosestPointError(ValueError):
    """Bad input for closest-point queries (shapes, NaNs, negative distances, empty mesh)."""


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
        v, f = _checked(vertices, faces)
        tri = v[f]                                                   # (m, 3, 3)
        lo, hi, child, start, count, order = build_bvh(
            np.ascontiguousarray(tri.min(axis=1)), np.ascontiguousarray(tri.max(axis=1)),
            np.ascontiguousarray(tri.mean(axis=1)), LEAF_SIZE)
        self._fid = order.astype(np.int64)
        self._set_corners(tri[order])
        self._nodes = (lo, hi, child, start, count)
        self.n_faces = len(f)

    def _set_corners(self, t: np.ndarray) -> None:
        """The triangles' corners (m, 3, 3) in leaf order, and which are degenerate."""
        self._A = np.ascontiguousarray(t[:, 0])
        self._B = np.ascontiguousarray(t[:, 1])
        self._C = np.ascontiguousarray(t[:, 2])
        ab, ac = self._B - self._A, self._C - self._A
        n2 = np.einsum("ij,ij->i", *(2 * [np.cross(ab, ac)]))
        scale = np.einsum("ij,ij->i", ab, ab) * np.einsum("ij,ij->i", ac, ac)
        self._flat = n2 <= 1e-20 * scale  # sin² of the angle at a: collinear or repeated corners

    @property
    def tree(self) -> tuple[np.ndarray, ...]:
        """The tree without its boxes (leaf order, children, leaf starts and counts), for
        :meth:`refitted`."""
        return (self._fid, *self._nodes[2:])

    @classmethod
    def refitted(cls, vertices: np.ndarray, faces: np.ndarray, tree: tuple[np.ndarray, ...]
                 ) -> "ClosestPointIndex":
        """The index of ``faces`` over ``vertices`` on the ``tree`` of an index of the same
        faces (over other vertices): its boxes refitted in one pass, no build. Queries are as
        exact as on a new index, and the same where the vertices are those the tree was built
        on; only ties between equally near triangles may resolve otherwise. The further the
        vertices moved, the less the tree prunes."""
        v, f = _checked(vertices, faces)
        fid, child, start, count = tree
        if len(f) != len(fid):
            raise ClosestPointError(f"the tree holds {len(fid)} faces, got {len(f)}")
        out = cls.__new__(cls)
        out._fid, out.n_faces = fid, len(fid)
        out._set_corners(v[f[fid]])
        out._nodes = (*refit_bvh(out._A, out._B, out._C, child, start, count), child, start,
                      count)
        return out

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


def _checked(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """(vertices as float64 (n, 3), faces as int64 (m, 3)), or ClosestPointError saying what
    is wrong with them."""
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
    return v, f.astype(np.int64)


_CACHE: "weakref.WeakKeyDictionary[TriMesh, ClosestPointIndex]" = weakref.WeakKeyDictionary()
_TREES: "weakref.WeakKeyDictionary[object, tuple]" = weakref.WeakKeyDictionary()


def closest_point_index(mesh: TriMesh) -> ClosestPointIndex:
    """The (cached) index of ``mesh``; a TriMesh is immutable, so it is built once per mesh."""
    idx = _CACHE.get(mesh)
    if idx is None:
        idx = _CACHE[mesh] = ClosestPointIndex(mesh.vertices, mesh.faces)
    return idx


def index_on(vertices: np.ndarray, faces: np.ndarray, owner: object) -> ClosestPointIndex:
    """The index of ``faces`` over ``vertices``, where ``owner`` fixes the faces (a micro-mesh
    topology: the fit's rounds move its vertices, never its triangles): built the first time,
    then that tree refitted (:meth:`ClosestPointIndex.refitted`), for as long as ``owner``
    lives. Only the tree is kept (about 25 bytes a face), not the corners."""
    tree = _TREES.get(owner)
    if tree is not None and len(tree[0]) == len(faces):
        return ClosestPointIndex.refitted(vertices, faces, tree)
    index = ClosestPointIndex(vertices, faces)
    _TREES[owner] = index.tree
    return index
