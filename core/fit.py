"""Least-squares fitting of micro-displacements to the reference surface (ours).

Projection baking samples the reference at each micro-vertex along its direction: the
piecewise-linear micro-surface interpolates those samples, so between them it cuts corners.
Fitting instead chooses all displacements together so that the micro-surface passes as close
as possible to the whole reference: dense samples on the reference (at least ``density`` per
micro-triangle, area-weighted), each matched to its closest point on the current micro-surface
(micro-triangle and barycentrics), and the point-to-plane residual along the reference normal

    r = n · (Σ_k b_k (P_k + D_k d_k) − s)

minimised in the least-squares sense together with ``slopes`` times the same weights on

    e = n · (X_b − X_a)   for each edge (a, b) of the matched micro-triangle,

which asks that triangle to lie in the sample's tangent plane, so that its normal, which flat
shading shows, is the reference's (distance alone lets a triangle tilt while its points stay
close), and ``smoothness`` · |L d|² (the micro
Laplacian, which keeps vertices without samples in place and damps noise). The matches are
renewed ``iterations`` times (an ICP on the displacements). The sparse normal equations are
solved by preconditioned conjugate gradients (:func:`solve_normal_equations`). Lengths are
those of the inputs (the construction calls it in the unit-sphere frame).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .closest import ClosestPointIndex
from .laplacian import uniform_laplacian
from .mesh import TriMesh
from .micromesh import MicroMesh

# At most 4**_MAX_LEVEL samples on one reference face.
_MAX_LEVEL = 5


class FitError(ValueError):
    """Inputs the fit cannot use."""


def _subtriangle_centroids(level: int) -> np.ndarray:
    """(4**level, 3) barycentrics of the centroids of a triangle's uniform subdivision."""
    r = 1 << level
    i, j = np.meshgrid(np.arange(r), np.arange(r), indexing="ij")
    up = i + j <= r - 1
    down = i + j <= r - 2
    u = np.concatenate([(i[up] + 1 / 3) / r, (i[down] + 2 / 3) / r])
    v = np.concatenate([(j[up] + 1 / 3) / r, (j[down] + 2 / 3) / r])
    return np.stack([1.0 - u - v, u, v], 1)


def reference_samples(reference: TriMesh, sample_area: float | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (s, 3), unit normals (s, 3), weights (s,)) on the reference's faces.

    Each face gets the centroids of its uniform subdivision at the level that makes a sample
    cover at most ``sample_area`` (4 samples at least, 4**5 at most), so large faces (the flat
    sides of CAD parts) are sampled as densely as the micro-mesh they must hold flat. Weights
    are the area each sample stands for, over their mean.
    """
    areas = reference.face_areas
    level = np.ones(len(areas), dtype=np.int64)
    if sample_area is not None:
        if not sample_area > 0:
            raise FitError("the sample area must be positive")
        with np.errstate(divide="ignore"):
            want = np.ceil(np.log(np.maximum(areas / sample_area, 1.0)) / np.log(4.0))
        level = np.clip(want.astype(np.int64), 1, _MAX_LEVEL)
    corners = reference.vertices[reference.faces]
    face_normals = reference.face_normals
    pts, normals, weights = [], [], []
    for lv in np.unique(level):
        faces = np.flatnonzero(level == lv)
        w = _subtriangle_centroids(int(lv))
        pts.append(np.einsum("sk,fkc->fsc", w, corners[faces]).reshape(-1, 3))
        normals.append(np.repeat(face_normals[faces], len(w), axis=0))
        weights.append(np.repeat(areas[faces] / len(w), len(w)))
    weights = np.concatenate(weights)
    return (np.concatenate(pts), np.concatenate(normals),
            weights / max(weights.mean(), 1e-300))


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


def fit_samples(mm: MicroMesh, reference: TriMesh, density: float = 2.0):
    """:func:`reference_samples` at least ``density`` per micro-triangle of ``mm``."""
    T = mm.topology.triangles
    area = _areas(mm.micro_vertex_positions(), T).sum()
    return reference_samples(reference, area / (len(T) * density))


def fit_displacements(mm: MicroMesh, reference: TriMesh, smoothness: float = 1e-3,
                      iterations: int = 2, density: float = 2.0, samples=None,
                      slopes: float = 0.1) -> np.ndarray:
    """Displacements (n,) of ``mm``'s micro-vertices fitted to ``reference`` (see the module
    docstring); ``mm``'s own displacements are the starting point.

    ``density``: reference samples per micro-triangle at least (large reference faces are
    subdivided for it). ``samples``: the output of
    :func:`reference_samples`, when the caller reuses it.
    """
    if smoothness < 0 or slopes < 0 or iterations < 1 or not density > 0:
        raise FitError("smoothness and slopes must be >= 0, iterations >= 1 and density > 0")
    if samples is None:
        samples = fit_samples(mm, reference, density)
    d = mm.displacements.copy()
    for _ in range(iterations):
        M, b = normal_equations(mm, d, samples, smoothness, slopes)
        d = solve_normal_equations(M, b, d)
    return np.asarray(d, dtype=np.float64)


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


def solve_normal_equations(M: sp.csr_matrix, b: np.ndarray, x0: np.ndarray,
                           rtol: float = 1e-10, maxiter: int = 2000, callback=None
                           ) -> np.ndarray:
    """x with M x = b (M symmetric positive definite): conjugate gradients with a Jacobi
    preconditioner from ``x0`` (the fit starts close to its answer: tens of iterations, 20-30
    times faster than a factorisation at 100k unknowns, ``bench/fit_bench.py``); a sparse
    factorisation where CG does not converge. ``callback``: called after each CG iteration."""
    diag = M.diagonal()
    if (diag > 0).all():
        x, info = spla.cg(M, b, x0=x0, rtol=rtol, maxiter=maxiter, M=sp.diags(1.0 / diag),
                          callback=callback)
        if info == 0 and np.isfinite(x).all():
            return x
    return spla.spsolve(M.tocsc(), b)


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


def _areas(X: np.ndarray, T: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]), axis=1)


def surface_errors(mm: MicroMesh, samples) -> tuple[np.ndarray, np.ndarray]:
    """(distance, normal) per base face (nf,) of the reference samples (of
    :func:`reference_samples`) whose nearest micro-surface point lies on that face: the
    weighted squared distance, and the weighted squared difference between the sample's normal
    and the micro-triangle's (what shading sees). Where the fitted micro-mesh still misses the
    reference."""
    pts, normals, weights = samples
    tess = mm.tessellate()
    V, T = tess.vertices, tess.triangles
    _, tri, dist = ClosestPointIndex(V, T).query(pts)
    tn = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    tn /= np.maximum(np.linalg.norm(tn, axis=1, keepdims=True), 1e-300)
    face = tess.triangle_face[tri]
    nf = mm.base.n_faces
    return (np.bincount(face, weights=weights * dist ** 2, minlength=nf),
            np.bincount(face, weights=weights * ((tn[tri] - normals) ** 2).sum(1), minlength=nf))
