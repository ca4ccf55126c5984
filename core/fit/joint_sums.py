"""The fit's normal equations over the displacements and the base vertices together (the base
round), summed in one compiled pass over the samples instead of sparse products of their rows.

Every row (a sample's point row and its three slope rows, see ``system``) has coefficients
c_k on the three corners of its micro-triangle, which all lie in one base face F; corner k's
base position is Σ_q W_kq V_q over F's three vertices. The row's coefficient on d_k is
α_k = c_k n·D_k, on coordinate a of F's vertex q it is β_aq = n_a Σ_k c_k W_kq, and its
right-hand side r = t − Σ_k c_k n·P_k. Each row adds w α αᵀ to the micro-triangle's 3 × 3
block, w α βᵀ to the (micro-vertex, base face) pairs' 3 × 9 coupling, w β βᵀ to the base
face's 9 × 9 block, and w α r, w β r to b.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..runtime.jit import kernel
from .triangle_sums import blocks_csr, csr_sum, f64


@kernel(cache=True)
def joint_sums(tri, corners, B, pts, normals, weights, P, D, slopes, tri_face, base_faces,
               slot, w_ptr, w_idx, w_val, n, nb, G, C, H, b):  # pragma: no cover
    """Add every sample's rows to ``G`` (m, 3, 3) (upper triangle), ``C`` (slots, 9) (the
    coupling of slot ``slot[t, i]`` = (corner i of triangle t, its base face) with that face's
    vertices' x, y, z), ``H`` (nf, 9, 9) and ``b`` (n + 3 nb,). ``w_ptr/w_idx/w_val``: the
    CSR arrays of the micro-vertices' interpolation of the base vertices."""
    Wk = np.zeros((3, 3))
    c = np.empty(3)
    g = np.empty(3)
    h = np.empty(3)
    al = np.empty(3)
    be = np.empty(9)
    for s in range(tri.shape[0]):
        t = tri[s]
        f = tri_face[t]
        nrm = normals[s]
        for k in range(3):
            v = corners[s, k]
            g[k] = nrm[0] * D[v, 0] + nrm[1] * D[v, 1] + nrm[2] * D[v, 2]
            h[k] = nrm[0] * P[v, 0] + nrm[1] * P[v, 1] + nrm[2] * P[v, 2]
            for q in range(3):
                Wk[k, q] = 0.0
                for e in range(w_ptr[v], w_ptr[v + 1]):
                    if w_idx[e] == base_faces[f, q]:
                        Wk[k, q] = w_val[e]
        for row in range(4):
            if row == 0:
                w = weights[s]
                target = nrm[0] * pts[s, 0] + nrm[1] * pts[s, 1] + nrm[2] * pts[s, 2]
                for k in range(3):
                    c[k] = B[s, k]
            else:
                if slopes <= 0.0:
                    break
                w = slopes * weights[s]
                target = 0.0
                for k in range(3):
                    c[k] = 0.0
                c[row - 1] = -1.0
                c[row % 3] = 1.0
            r = target
            for k in range(3):
                al[k] = c[k] * g[k]
                r -= c[k] * h[k]
            for q in range(3):
                u = c[0] * Wk[0, q] + c[1] * Wk[1, q] + c[2] * Wk[2, q]
                for a in range(3):
                    be[a * 3 + q] = nrm[a] * u
            for i in range(3):
                for j in range(i, 3):
                    G[t, i, j] += w * al[i] * al[j]
                si = slot[t, i]
                for x in range(9):
                    C[si, x] += w * al[i] * be[x]
                b[corners[s, i]] += w * al[i] * r
            for x in range(9):
                for y in range(9):
                    H[f, x, y] += w * be[x] * be[y]
                b[n + (x // 3) * nb + base_faces[f, x % 3]] += w * be[x] * r


def joint_system(matches, T, P, D, W, topology, base_faces, slopes: float
                 ) -> tuple[sp.csr_matrix, np.ndarray]:
    """(M, b) over the displacements (n) and the base offsets (3 nb, x then y then z), the
    system ``rows.row_system`` builds from the rows with ``W``; ``matches`` as
    ``system.sample_matches`` yields them."""
    n, nb, m, nf = len(P), W.shape[1], len(T), len(base_faces)
    tri_face = np.ascontiguousarray(topology.triangle_face, dtype=np.int64)
    key = (T.astype(np.int64) * nf + tri_face[:, None]).reshape(-1)
    pairs, slot = np.unique(key, return_inverse=True)     # (micro-vertex, base face) pairs
    G, C = np.zeros((m, 3, 3)), np.zeros((len(pairs), 9))
    H, b = np.zeros((nf, 9, 9)), np.zeros(n + 3 * nb)
    i64 = lambda x: np.ascontiguousarray(x, dtype=np.int64)  # noqa: E731
    slot, faces = i64(slot.reshape(m, 3)), i64(base_faces)
    P, D, w_ptr, w_idx, w_val = f64(P), f64(D), i64(W.indptr), i64(W.indices), f64(W.data)
    for pts, normals, weights, tri, corners, B in matches:
        joint_sums(i64(tri), corners, B, f64(pts), f64(normals), f64(weights), P, D,
                   float(slopes), tri_face, faces, slot, w_ptr, w_idx, w_val, n, nb, G, C, H, b)
    del slot
    size = n + 3 * nb
    # The parts summed one at a time (csr_sum), each freed before the next is made.
    M = blocks_csr(G, T, size)
    del G
    face_of = pairs % nf
    base_col = n + np.arange(3)[None, :, None] * nb + base_faces[face_of][:, None, :]  # (p, 3, 3)
    coupling = csr_sum(np.repeat(pairs // nf, 9), base_col.reshape(-1), C.reshape(-1), size)
    del C, base_col, face_of, pairs
    M = M + coupling + coupling.T.tocsr()
    del coupling
    hb = (n + np.arange(3)[None, :, None] * nb + base_faces[:, None, :]).reshape(nf, 9)
    M = M + csr_sum(np.repeat(hb, 9, axis=1).reshape(-1), np.tile(hb, (1, 9)).reshape(-1),
                 H.reshape(-1), size)
    return M, b
