"""The fit's displacement-only normal equations summed per micro-triangle, compiled: one pass
over the samples, no per-sample temporaries (``docs/results.md`` has the timings).

A sample matched to a micro-triangle with corners k (barycentrics B_k, g_k = n·D_k,
h_k = n·P_k) adds w g_i g_j (B_i B_j + slopes (3 δ_ij − 1)) to the triangle's 3 × 3 block
(its point row and its three slope rows) and w (B_i g_i (n·s − Σ_k B_k h_k)
+ slopes g_i (Σ_k h_k − 3 h_i)) to b at corner i.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..runtime.jit import kernel


@kernel(cache=True)
def triangle_sums(tri, corners, B, pts, normals, weights, P, D, slopes, G, b):  # pragma: no cover
    """Add every sample's terms to ``G`` (m, 3, 3), upper triangle of each block, and ``b``
    (n,). ``tri`` (s,) matched micro-triangles, ``corners`` (s, 3) their vertices, ``B`` (s, 3)
    barycentrics, ``pts``/``normals`` (s, 3), ``weights`` (s,), ``P``/``D`` (n, 3) the
    micro-vertices' base positions and directions."""
    g = np.empty(3)
    h = np.empty(3)
    a = np.empty(3)
    for s in range(tri.shape[0]):
        t = tri[s]
        nx, ny, nz = normals[s, 0], normals[s, 1], normals[s, 2]
        w = weights[s]
        point = nx * pts[s, 0] + ny * pts[s, 1] + nz * pts[s, 2]
        hs = 0.0
        for k in range(3):
            c = corners[s, k]
            g[k] = nx * D[c, 0] + ny * D[c, 1] + nz * D[c, 2]
            h[k] = nx * P[c, 0] + ny * P[c, 1] + nz * P[c, 2]
            a[k] = B[s, k] * g[k]
            point -= B[s, k] * h[k]
            hs += h[k]
        for i in range(3):
            for j in range(i, 3):
                mask = 2.0 if i == j else -1.0
                G[t, i, j] += w * (a[i] * a[j] + slopes * mask * g[i] * g[j])
            b[corners[s, i]] += w * (a[i] * point + slopes * g[i] * (hs - 3.0 * h[i]))


def f64(x: np.ndarray) -> np.ndarray:
    """``x`` as a contiguous float64 array (no copy where it is one), as the kernels take it."""
    return np.ascontiguousarray(x, dtype=np.float64)


def block_entries(G: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows, cols, values) of the symmetric 3 x 3 blocks ``G`` (m, 3, 3), upper triangle
    stored, at the corners ``T`` (m, 3) of their micro-triangles (duplicates to be summed)."""
    iu = [(i, j) for i in range(3) for j in range(3)]
    return (np.concatenate([T[:, i] for i, j in iu]), np.concatenate([T[:, j] for i, j in iu]),
            np.concatenate([G[:, min(i, j), max(i, j)] for i, j in iu]))


def _index(size: int):
    return np.int32 if size < np.iinfo(np.int32).max else np.int64


def csr_sum(rows, cols, values, size: int) -> sp.csr_matrix:
    """(size, size) CSR of the triplets, duplicates summed, with int32 indices where they fit
    (one part of a system at a time: a COO of all the entries at once took about twice the
    memory of the matrix it becomes, the fit's peak on large inputs)."""
    index = _index(size)
    return sp.coo_matrix((values, (rows.astype(index, copy=False), cols.astype(index, copy=False))),
                         shape=(size, size)).tocsr()


def blocks_csr(G: np.ndarray, T: np.ndarray, size: int) -> sp.csr_matrix:
    """:func:`csr_sum` of :func:`block_entries` (the corners narrowed to the index type
    first, so that the triplets are made in it)."""
    return csr_sum(*block_entries(G, T.astype(_index(size), copy=False)), size)


class BlockOperator:
    """M = Σ over micro-triangles of each one's symmetric 3 x 3 block ``G`` (m, 3, 3), upper
    triangle given (:func:`triangle_sums`), at its corners ``T`` (m, 3), plus diag(``hold``)
    (n,): applied as blocks, never made a matrix. ``G`` is made symmetric in place."""

    def __init__(self, G: np.ndarray, T: np.ndarray, hold: np.ndarray):
        for i, j in ((0, 1), (0, 2), (1, 2)):
            G[:, j, i] = G[:, i, j]
        self.G, self.T, self.hold = G, T, hold
        self.shape = (len(hold), len(hold))

    def diagonal(self) -> np.ndarray:
        n = len(self.hold)
        return self.hold + sum(np.bincount(self.T[:, k], self.G[:, k, k], minlength=n)
                               for k in range(3))

    def __matmul__(self, v: np.ndarray) -> np.ndarray:
        """M v for v (n,)."""
        out = self.hold * v
        apply_blocks(self.G, self.T, f64(v), out)
        return out


@kernel(cache=True)
def apply_blocks(G, T, v, out):  # pragma: no cover
    """out += Σ_t G_t v[T_t] at T_t, triangle by triangle in order (one thread: the sums do
    not depend on the thread count), in float64 from ``G``'s float32."""
    for t in range(T.shape[0]):
        a, b, c = T[t, 0], T[t, 1], T[t, 2]
        va, vb, vc = v[a], v[b], v[c]
        out[a] += np.float64(G[t, 0, 0]) * va + np.float64(G[t, 0, 1]) * vb \
            + np.float64(G[t, 0, 2]) * vc
        out[b] += np.float64(G[t, 1, 0]) * va + np.float64(G[t, 1, 1]) * vb \
            + np.float64(G[t, 1, 2]) * vc
        out[c] += np.float64(G[t, 2, 0]) * va + np.float64(G[t, 2, 1]) * vb \
            + np.float64(G[t, 2, 2]) * vc
