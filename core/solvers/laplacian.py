"""Mesh Laplacians as scipy sparse matrices: uniform (graph) and cotangent weights; the screened
solve of the Large-Steps reparameterisation over them is :mod:`core.solvers.screened`."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp



class LaplacianError(ValueError):
    """Bad input for a Laplacian or screened solve (shapes, indices, NaNs, λ)."""


def _check_faces(n_vertices: int, faces: np.ndarray) -> np.ndarray:
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3:
        raise LaplacianError(f"faces must be (m, 3), got {f.shape}")
    f = f.astype(np.int64, copy=False)
    if n_vertices < 1:
        raise LaplacianError("need at least one vertex")
    if len(f) and (f.min() < 0 or f.max() >= n_vertices):
        raise LaplacianError("face index out of range")
    return f


def _from_weights(n: int, i: np.ndarray, j: np.ndarray, w: np.ndarray) -> sp.csr_matrix:
    """L = D − W for symmetric off-diagonal weights given once per (i, j) occurrence."""
    rows = np.concatenate([i, j])
    cols = np.concatenate([j, i])
    vals = np.concatenate([w, w])
    W = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))  # duplicates are summed
    W.setdiag(0.0)  # self-loops from degenerate faces carry no meaning
    W.eliminate_zeros()
    deg = np.asarray(W.sum(axis=1)).ravel()
    L = (sp.diags(deg) - W).tocsr()
    L.sort_indices()
    return L


def uniform_laplacian(n_vertices: int, faces: np.ndarray) -> sp.csr_matrix:
    """Graph Laplacian D − A over the mesh edges (each edge weight 1, however many faces share it)."""
    f = _check_faces(n_vertices, faces)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    e = np.sort(e, axis=1)
    e = e[e[:, 0] != e[:, 1]]
    key = np.unique(e[:, 0] * np.int64(n_vertices) + e[:, 1])
    i, j = key // n_vertices, key % n_vertices
    return _from_weights(n_vertices, i, j, np.ones(len(key)))


def cotangent_weights(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m, 3) cot of the angle at corner k of each face; all 0 on a degenerate face.

    A face is degenerate when twice its area is below 1e-12 of its squared longest edge;
    dropping it keeps L finite and PSD (each face's contribution is PSD on its own).
    """
    p = np.asarray(vertices, dtype=np.float64)[faces]  # (m, 3, 3)
    e = [p[:, (k + 2) % 3] - p[:, (k + 1) % 3] for k in range(3)]  # edge opposite corner k
    cross = np.linalg.norm(np.cross(e[1], e[2]), axis=1)  # twice the area
    longest = np.max(np.stack([np.einsum("ij,ij->i", x, x) for x in e]), axis=0)
    ok = cross > 1e-12 * longest
    safe = np.where(ok, cross, 1.0)
    out = np.empty(faces.shape, dtype=np.float64)
    for k in range(3):
        a = p[:, (k + 1) % 3] - p[:, k]
        b = p[:, (k + 2) % 3] - p[:, k]
        out[:, k] = np.where(ok, np.einsum("ij,ij->i", a, b) / safe, 0.0)
    return out


def cotangent_laplacian(vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """Cotangent Laplacian: L_ij = −½(cot α + cot β) off the diagonal, rows sum to 0 (PSD)."""
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise LaplacianError(f"vertices must be (n, 3), got {v.shape}")
    if not np.isfinite(v).all():
        raise LaplacianError("vertices contain NaN or infinity")
    f = _check_faces(len(v), faces)
    cot = cotangent_weights(v, f)
    # The angle at corner k is opposite the edge (k+1, k+2).
    i = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    j = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    w = 0.5 * np.concatenate([cot[:, 0], cot[:, 1], cot[:, 2]])
    return _from_weights(len(v), i, j, w)
