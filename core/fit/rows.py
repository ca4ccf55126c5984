"""The fit's normal equations from the rows themselves (the general way): each sample's
point row and slope rows as a sparse matrix over the displacements and, with the base's
interpolation ``W``, the base vertices, then AᵀWA. The compiled sums (``triangle_sums``,
``joint_sums``) give the same system without the rows; the tests and
``bench/fit_bench.py`` compare them with this."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def row_system(matches, P, D, W, size, slopes):
    """(M, b) from the rows themselves: over the displacements and, with ``W``, the base
    vertices."""
    n = len(P)
    M, b = sp.csr_matrix((size, size)), np.zeros(size)
    for pts, normals, weights, _, corners, B in matches:
        C, N, t, w = _rows(corners, B, pts, normals, weights, n, slopes)
        A, rhs = _columns(C, N, t, P, D, W)
        AtW = A.T.multiply(w[None, :]).tocsr()
        M = M + AtW @ A
        b += AtW @ rhs
    return M, b


def _columns(C, N, t, P, D, W):
    """(A, rhs) of rows ``C`` along normals ``N`` with targets ``t``: the displacements'
    columns (c_k n·D_k) and, with ``W``, the base vertices' (n_a (C W)), and t − n·(C P)."""
    coo = C.tocoo()
    A = sp.csr_matrix((coo.data * (N[coo.row] * D[coo.col]).sum(1), (coo.row, coo.col)),
                      shape=C.shape)
    rhs = t - sum(N[:, a] * (C @ P[:, a]) for a in range(3))
    if W is not None:
        CW = (C @ W).tocsr()
        A = sp.hstack([A] + [CW.multiply(N[:, a:a + 1]) for a in range(3)]).tocsr()
    return A, rhs


def _rows(corners, B, pts, normals, weights, n: int, slopes: float):
    """(C (r, n) coefficients, N (r, 3) normals, t (r,) targets, w (r,) weights) of the point
    rows of samples matched to micro-triangles ``corners`` at barycentrics ``B`` and, with
    ``slopes`` > 0, the slope rows (weight ``slopes`` times the sample's)."""
    s = len(pts)
    rows, cols, vals = [np.repeat(np.arange(s), 3)], [corners.reshape(-1)], [B.reshape(-1)]
    N, t, w = [normals], [(normals * pts).sum(1)], [weights]
    if slopes > 0:
        for e, (a, b) in enumerate(((0, 1), (1, 2), (2, 0))):
            rows.append(np.repeat(np.arange((e + 1) * s, (e + 2) * s), 2))
            cols.append(corners[:, [a, b]].reshape(-1))
            vals.append(np.tile([-1.0, 1.0], s))
            N.append(normals)
            t.append(np.zeros(s))
            w.append(slopes * weights)
    r = s * (4 if slopes > 0 else 1)
    C = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(r, n))
    return C, np.concatenate(N), np.concatenate(t), np.concatenate(w)

