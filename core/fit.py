"""Least-squares fitting of micro-displacements to the reference surface (ours).

Projection baking samples the reference at each micro-vertex along its direction: the
piecewise-linear micro-surface interpolates those samples, so between them it cuts corners.
Fitting instead chooses all displacements together so that the micro-surface passes as close
as possible to the whole reference: dense samples on the reference (``samples_per_face`` per
face, area-weighted), each matched to its closest point on the current micro-surface
(micro-triangle and barycentrics), and the point-to-plane residual along the reference normal

    r = n · (Σ_k b_k (P_k + D_k d_k) − s)

minimised in the least-squares sense together with ``smoothness`` · |L d|² (the micro
Laplacian, which keeps vertices without samples in place and damps noise). The matches are
renewed ``iterations`` times (an ICP on the displacements). The sparse normal equations are
solved by a sparse factorisation. Lengths are those of the inputs (the construction calls it
in the unit-sphere frame).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .closest import ClosestPointIndex
from .laplacian import uniform_laplacian
from .mesh import TriMesh
from .micromesh import MicroMesh

# Sample points per reference face, as barycentric weights.
_SAMPLES = {1: np.array([[1 / 3, 1 / 3, 1 / 3]]),
            4: np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3],
                         [1 / 3, 1 / 3, 1 / 3]])}


class FitError(ValueError):
    """Inputs the fit cannot use."""


def reference_samples(reference: TriMesh, per_face: int = 4
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (s, 3), unit normals (s, 3), weights (s,)) on the reference's faces."""
    if per_face not in _SAMPLES:
        raise FitError(f"samples per face must be one of {sorted(_SAMPLES)}")
    w = _SAMPLES[per_face]
    pts = np.einsum("sk,fkc->fsc", w, reference.vertices[reference.faces]).reshape(-1, 3)
    normals = np.repeat(reference.face_normals, per_face, axis=0)
    weights = np.repeat(reference.face_areas / per_face, per_face)
    return pts, normals, weights / max(weights.mean(), 1e-300)


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


def fit_displacements(mm: MicroMesh, reference: TriMesh, smoothness: float = 1e-3,
                      iterations: int = 2, samples_per_face: int = 4,
                      samples=None) -> np.ndarray:
    """Displacements (n,) of ``mm``'s micro-vertices fitted to ``reference`` (see the module
    docstring); ``mm``'s own displacements are the starting point. ``samples``: the output of
    :func:`reference_samples`, when the caller reuses it."""
    if smoothness < 0 or iterations < 1:
        raise FitError("smoothness must be >= 0 and iterations >= 1")
    pts, normals, weights = samples if samples is not None else \
        reference_samples(reference, samples_per_face)
    P, D = mm.micro_vertex_base_positions(), mm.micro_vertex_directions()
    T = mm.tessellate().triangles
    T = T[(T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 2] != T[:, 0])]
    n = mm.n_vertices
    L = uniform_laplacian(n, T)
    reg = smoothness * (L.T @ L) + 1e-9 * sp.eye(n)
    d = mm.displacements.copy()
    for _ in range(iterations):
        X = P + D * d[:, None]
        cp, tri, _ = ClosestPointIndex(X, T).query(pts)
        corners = T[tri]                                          # (s, 3)
        B = _barycentrics(cp, X[corners[:, 0]], X[corners[:, 1]], X[corners[:, 2]])
        nD = np.einsum("sc,skc->sk", normals, D[corners])
        nP = np.einsum("sc,skc->sk", normals, P[corners])
        A = sp.csr_matrix(((B * nD).reshape(-1),
                           (np.repeat(np.arange(len(pts)), 3), corners.reshape(-1))),
                          shape=(len(pts), n))
        rhs = (normals * pts).sum(1) - (B * nP).sum(1)
        AtW = A.T.multiply(weights[None, :]).tocsr()
        M = (AtW @ A + reg).tocsc()
        d = spla.spsolve(M, AtW @ rhs + 1e-9 * d)
    return np.asarray(d, dtype=np.float64)
