"""The least-volume direction bounds (ours): two linear programmes that hold every
micro-vertex as a file folds the bounds, for the least shell (:func:`lp_bounds`)."""
from __future__ import annotations

import numpy as np

from .bounds import DirectionBounds, tight_bounds
from .micromesh import MicroMesh


def lp_bounds(mm: MicroMesh, min_scale: float = 1e-6, smoothing: float = 0.0) -> DirectionBounds:
    """The bounds of least shell volume that still hold every micro-vertex (ours).

    A micro-vertex k with barycentrics W_kj in its base face needs only its own interpolated
    bounds to hold it, not every vertex's bounds to hold the whole one ring
    (``core.micro.bounds.tight_bounds``). Folded into a file (``core.micro.bounds.baked``), vertex j's
    bound b_j moves k by W_kj b_j D_j, which is A_kj b_j = W_kj (D_j · L_k) / |L_k|² b_j along
    k's interpolated direction L_k = Σ_j W_kj D_j (:func:`_along`; W_kj where the directions
    agree). So k needs Σ_j A_kj bias_j ≤ d_k ≤ Σ_j A_kj (bias_j + scale_j). The shell volume
    is about Σ_j a_j |D_j| scale_j (a_j: a third of the area of the faces around vertex j), so
    the lower and the upper bounds are two linear programmes: maximise Σ a_j |D_j| bias_j
    subject to A bias ≤ d, and minimise the same sum of the upper bounds subject to
    A upper ≥ d (HiGHS, a second or two for 10k base vertices). Where a programme fails,
    ``tight_bounds``. (With W for A, micro-vertices left their place once folded wherever
    the directions differ across a face: docs/results.md, thirty-fifth session.)

    What remains of that is across the interpolated direction. ``smoothing`` (μ ≥ 0) adds
    μ · ½(w_i + w_j) · |D̂_i − D̂_j| · |bound_i − bound_j| per base edge to each programme's
    objective (w: the weights above): bounds may still differ where the directions agree, and
    are drawn together where they do not.
    """
    from scipy.optimize import linprog
    import scipy.sparse as sp

    R = _along(mm)                  # the containment rows
    w, length = shell_weights(mm)
    used = np.diff(R.tocsc().indptr) > 0
    free = [(None, None) if u else (0.0, 0.0) for u in used]
    d = mm.displacements
    A, cost = R, np.zeros(0)
    if smoothing > 0:
        G, cost = _smoothing_rows(mm, w, length, smoothing)
        A = sp.vstack([sp.hstack([R, sp.csr_matrix((R.shape[0], len(cost)))]), G]).tocsr()
        free = free + [(0.0, None)] * len(cost)
        d = np.concatenate([d, np.zeros(G.shape[0])])
    n = len(w)
    sign = np.ones(A.shape[0])
    sign[:R.shape[0]] = -1.0        # the rows of R flip for the upper bounds, the edges' not
    low = linprog(np.concatenate([-w, cost]), A_ub=A, b_ub=d, bounds=free, method="highs")
    high = linprog(np.concatenate([w, cost]), A_ub=sp.diags(sign) @ A, b_ub=sign * d,
                   bounds=free, method="highs")
    if low.status != 0 or high.status != 0:
        return tight_bounds(mm, min_scale)
    return DirectionBounds(low.x[:n], np.maximum(high.x[:n] - low.x[:n], min_scale))


def _along(mm: MicroMesh):
    """(micro-vertices, base vertices) sparse A_kj = W_kj (D_j · L_k) / |L_k|², L_k = Σ_j W_kj
    D_j: how far along L_k a unit bound at base vertex j moves micro-vertex k once folded
    (:func:`lp_bounds`); W_kj where L_k vanishes."""
    import scipy.sparse as sp

    W = mm.topology.interp.tocoo()
    L = mm.micro_vertex_directions()
    nn = (L * L).sum(1)
    along = (L[W.row] * mm.directions[W.col]).sum(1) / np.maximum(nn[W.row], 1e-300)
    vals = W.data * np.where(nn[W.row] > 1e-24, along, 1.0)
    return sp.csr_matrix((vals, (W.row, W.col)), shape=W.shape)


def shell_weights(mm: MicroMesh) -> tuple[np.ndarray, np.ndarray]:
    """(w, |D|) per base vertex: a third of the area of the faces around it times its
    direction's length |D| (the shell's volume is about Σ w · scale)."""
    V, F = mm.base.vertices, mm.base.faces
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]),
                                axis=1)
    w = np.zeros(len(V))
    np.add.at(w, F.reshape(-1), np.repeat(area / 3.0, 3))
    length = np.linalg.norm(mm.directions, axis=1)
    return w * length, length


def _smoothing_rows(mm: MicroMesh, w: np.ndarray, length: np.ndarray, smoothing: float):
    """For :func:`lp_bounds`: one more variable e per base edge (i, j), the rows
    ±(bound_i − bound_j) − e ≤ 0 (2E, nv + E) and e's cost μ · ½(w_i + w_j) · |D̂_i − D̂_j|."""
    import scipy.sparse as sp

    i, j = mm.base.edges.T
    nv, ne = len(w), len(i)
    unit = mm.directions / np.maximum(length, 1e-300)[:, None]
    cost = smoothing * 0.5 * (w[i] + w[j]) * np.linalg.norm(unit[i] - unit[j], axis=1)
    r = np.arange(ne)
    rows = np.tile(np.concatenate([r, r + ne]), 3)
    cols = np.concatenate([i, i, j, j, nv + r, nv + r])
    one = np.ones(ne)
    vals = np.concatenate([one, -one, -one, one, -one, -one])
    return sp.csr_matrix((vals, (rows, cols)), shape=(2 * ne, nv + ne)), cost
