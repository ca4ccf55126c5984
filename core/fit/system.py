"""The normal equations of one fit round: samples matched to the micro-surface, the
point-to-plane and slope rows, the smoothness term."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..closest import ClosestPointIndex
from ..laplacian import uniform_laplacian
from ..micromesh import MicroMesh


def normal_equations(mm: MicroMesh, d: np.ndarray, samples, smoothness: float, slopes: float
                     ) -> tuple[sp.csr_matrix, np.ndarray]:
    """(M (n, n), b (n,)) of one fit round: the samples matched to their closest points on
    the micro-surface of displacements ``d``, then the weighted least-squares system."""
    P, D = mm.micro_vertex_base_positions(), mm.micro_vertex_directions()
    T = mm.topology.triangles                  # the non-degenerate micro-triangles
    n = mm.n_vertices
    pts, normals, weights = samples
    X = P + D * d[:, None]
    cp, tri, _ = ClosestPointIndex(X, T).query(pts)
    corners = T[tri]                                          # (s, 3)
    B = _barycentrics(cp, X[corners[:, 0]], X[corners[:, 1]], X[corners[:, 2]])
    nD = np.einsum("sc,skc->sk", normals, D[corners])
    nP = np.einsum("sc,skc->sk", normals, P[corners])
    A, rhs, w = _point_rows(B, nD, nP, corners, n, (normals * pts).sum(1), weights)
    if slopes > 0:
        A, rhs, w = _stack((A, rhs, w), _slope_rows(nD, nP, corners, n, slopes * weights))
    AtW = A.T.multiply(w[None, :]).tocsr()
    L = uniform_laplacian(n, T)
    M = AtW @ A + smoothness * (L.T @ L) + 1e-9 * sp.eye(n)
    return M.tocsr(), AtW @ rhs + 1e-9 * d


def _barycentrics(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(s, 3) barycentrics of points p in triangles (a, b, c) (p on the triangle)."""
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    ok = np.abs(den) > 1e-300
    den = np.where(ok, den, 1.0)
    bv = np.where(ok, (d11 * d20 - d01 * d21) / den, 1 / 3)
    bw = np.where(ok, (d00 * d21 - d01 * d20) / den, 1 / 3)
    return np.stack([1.0 - bv - bw, bv, bw], 1)


def _point_rows(B, nD, nP, corners, n, target, weights):
    """Rows of the point-to-plane residuals: n·(Σ b_k (P_k + D_k d_k)) = n·s."""
    s = len(B)
    A = sp.csr_matrix(((B * nD).reshape(-1), (np.repeat(np.arange(s), 3), corners.reshape(-1))),
                      shape=(s, n))
    return A, target - (B * nP).sum(1), weights


def _slope_rows(nD, nP, corners, n, weights):
    """Rows of the slope residuals: n·(X_b − X_a) = 0 for the three edges of each matched
    micro-triangle (X_k = P_k + D_k d_k)."""
    s = len(nD)
    rows = np.repeat(np.arange(3 * s), 2)
    vals, cols, rhs = [], [], []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        vals.append(np.stack([-nD[:, a], nD[:, b]], 1))
        cols.append(np.stack([corners[:, a], corners[:, b]], 1))
        rhs.append(nP[:, a] - nP[:, b])
    A = sp.csr_matrix((np.concatenate(vals).reshape(-1), (rows, np.concatenate(cols).reshape(-1))),
                      shape=(3 * s, n))
    return A, np.concatenate(rhs), np.tile(weights, 3)


def _stack(*blocks):
    return (sp.vstack([b[0] for b in blocks]).tocsr(), np.concatenate([b[1] for b in blocks]),
            np.concatenate([b[2] for b in blocks]))
