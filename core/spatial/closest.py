"""Exact closest point on a triangle mesh: a BVH over the triangles, queried in parallel (numba).

Build: :mod:`core.spatial.bvh` (leaves of at most ``LEAF_SIZE`` triangles), then the triangles'
corners copied in leaf order so a leaf reads contiguous memory.

Query: :mod:`core.spatial.bvh_query` (the tree's traversal, in parallel over blocks of points).
Degenerate (zero-area) triangles fall back to the nearest of their three edges (flagged at
build: squared sine of the angle at a corner ≤ 1e-20).
"""
from __future__ import annotations

import weakref

import numpy as np

from .bvh import build_bvh, refit_bvh
from .bvh_query import query_nearest
from .point_triangle import degenerate
from .checks import as_points, per_point_distance
from ..mesh.trimesh import TriMesh
from ..runtime.threads import parallel_for

LEAF_SIZE = 4
_BLOCK = 256          # points per parallel work item


class ClosestPointError(ValueError):
    """Bad input for closest-point queries (shapes, NaNs, negative distances, empty mesh)."""


class ClosestPointIndex:
    """BVH over a triangle mesh for exact closest-point queries; build once, query often.

    ``vertices`` (n, 3) float, ``faces`` (m, 3) int. Degenerate triangles are allowed (they act
    as segments or points). Queries run on ``core.runtime.threads.parallel_for``.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        v, f = _checked(vertices, faces)
        a, b, c = (v[f[:, k]] for k in range(3))        # (no (m, 3, 3) copy: 72 B a face)
        lo, hi, child, start, count, order = build_bvh(
            np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c),
            (a + b + c) / 3.0, LEAF_SIZE)
        self._fid = order.astype(np.int64)
        self._set_corners(a[order], b[order], c[order])
        self._nodes = (lo, hi, child, start, count)
        self.n_faces = len(f)

    def _set_corners(self, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> None:
        """The triangles' corners (m, 3) each, in leaf order, and which are degenerate."""
        self._A, self._B, self._C = a, b, c
        self._flat = degenerate(a, b, c)

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
        ff = f[fid]
        out._set_corners(*(v[ff[:, k]] for k in range(3)))
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
        ``threads``: threads for this call only (default: ``runtime.threads.threads()``).
        """
        q = as_points(points, "points", ClosestPointError)
        n = len(q)
        md = per_point_distance(max_distance, n, ClosestPointError)
        out_p = np.empty((n, 3))
        out_f = np.empty(n, np.int64)
        out_d2 = np.empty(n)
        if n:
            parallel_for(query_nearest, -(-n // _BLOCK), np.ascontiguousarray(q),
                         md * md * (1 + 1e-14), *self._nodes, self._A, self._B, self._C,
                         self._flat, self._fid, _BLOCK, out_p, out_f, out_d2, workers=threads)
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
