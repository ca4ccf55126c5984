"""Per-base-vertex direction bounds and the prismoid shell they span.

With bounds (bias b, scale s) a micro-vertex is stored as a value t in [0, 1]:
position = lerp(P + D·b) + lerp(D·s) · t (``docs/micromesh-format.md``). Tight bounds make a
thin shell: fast ray tracing and fine quantisation. The shell volume (sum of the prismoids
between the t = 0 and t = 1 triangles) is the metric of ``docs/method.md`` §7.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .micromesh import MicroMesh


class BoundsError(ValueError):
    """Bounds that do not fit the mesh."""


@dataclass(eq=False)
class DirectionBounds:
    """Per base vertex: displacement range [bias, bias + scale]."""

    bias: np.ndarray   # (nv,)
    scale: np.ndarray  # (nv,)

    def __post_init__(self) -> None:
        self.bias = np.ascontiguousarray(self.bias, dtype=np.float64)
        self.scale = np.ascontiguousarray(self.scale, dtype=np.float64)
        if self.bias.ndim != 1 or self.bias.shape != self.scale.shape:
            raise BoundsError(f"bias and scale must be (nv,) arrays of one shape, got "
                              f"{self.bias.shape} and {self.scale.shape}")


def tight_bounds(mm: MicroMesh, min_scale: float = 1e-6) -> DirectionBounds:
    """For each base vertex, min and max displacement over all micro-vertices of the base
    faces around it: bias = min, scale = max − min (at least ``min_scale``)."""
    t = mm.topology
    vals = mm.displacements[t.face_vertex_idx]
    starts = t.face_vertex_ptr[:-1]
    fmin, fmax = np.minimum.reduceat(vals, starts), np.maximum.reduceat(vals, starts)
    nv = mm.base.n_vertices
    vmin, vmax = np.full(nv, np.inf), np.full(nv, -np.inf)
    for i in range(3):
        np.minimum.at(vmin, mm.base.faces[:, i], fmin)
        np.maximum.at(vmax, mm.base.faces[:, i], fmax)
    unused = ~np.isfinite(vmin)
    vmin[unused], vmax[unused] = 0.0, 0.0
    return DirectionBounds(vmin, np.maximum(vmax - vmin, min_scale))


def reach(mm: MicroMesh) -> np.ndarray:
    """(nv,) per base vertex, the length its micro-vertices' displacements span along its
    direction (its tight bounds' range times |D|): its share of the shell's thickness."""
    return tight_bounds(mm, 0.0).scale * np.linalg.norm(mm.directions, axis=1)


def lp_bounds(mm: MicroMesh, min_scale: float = 1e-6, smoothing: float = 0.0) -> DirectionBounds:
    """The bounds of least shell volume that still hold every micro-vertex (ours).

    A micro-vertex k with barycentrics W_kj in its base face needs only its own interpolated
    bounds to hold it, not every vertex's bounds to hold the whole one ring
    (:func:`tight_bounds`). Folded into a file (:func:`baked`), vertex j's bound b_j moves k
    by W_kj b_j D_j, which is W_kj (D_j · L_k) / |L_k|² b_j along k's interpolated direction
    L_k = Σ_j W_kj D_j (A_kj: :func:`_along`; W_kj where the directions agree). So k needs
    Σ_j A_kj bias_j ≤ d_k ≤ Σ_j A_kj (bias_j + scale_j). The shell volume is about
    Σ_j a_j |D_j| scale_j (a_j: a third of the area of the faces around vertex j), so the
    lower and the upper bounds are two linear programmes: maximise Σ a_j |D_j| bias_j subject
    to A bias ≤ d, and minimise the same sum of the upper bounds subject to A upper ≥ d
    (HiGHS, a second or two for 10k base vertices). Where a programme fails,
    :func:`tight_bounds`. (With W for A, bounds that differ across a face where the directions
    differ too left micro-vertices off their place once folded: the helmet's image error rose
    by 4 % against 2.5 % at μ = 0, docs/results.md.)

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


def normalized_values(mm: MicroMesh, bounds: DirectionBounds, clip: bool = True) -> np.ndarray:
    """(n,) value t per micro-vertex with lerp(P + D·b) + lerp(D·s)·t closest (least squares
    along lerp(D·s)) to its position; clipped to [0, 1] unless ``clip`` is False (then values
    outside show where varying directions leave the shell)."""
    nv = mm.base.n_vertices
    if bounds.bias.shape != (nv,):
        raise BoundsError(f"bounds must have one entry per base vertex ({nv})")
    interp = mm.topology.interp
    D = mm.directions
    Q = interp @ (mm.base.vertices + D * bounds.bias[:, None])
    S = interp @ (D * bounds.scale[:, None])
    r = mm.micro_vertex_positions() - Q
    nn = (S * S).sum(1)
    t = (S * r).sum(1) / np.maximum(nn, 1e-300)
    t = np.where(nn > 1e-300, t, 0.0)
    return np.clip(t, 0.0, 1.0) if clip else t


def prismoid_volumes(base_vertices: np.ndarray, faces: np.ndarray, directions: np.ndarray,
                     bounds: DirectionBounds) -> np.ndarray:
    """(nf,) volume between the t = 0 triangle (P + D·b) and the t = 1 triangle
    (P + D·(b + s)) of each face, as three tetrahedra (absolute volumes)."""
    P = np.asarray(base_vertices, dtype=np.float64)
    D = np.asarray(directions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if P.shape != D.shape or P.ndim != 2 or P.shape[1] != 3:
        raise BoundsError("base_vertices and directions must both be (nv, 3)")
    if bounds.bias.shape != (len(P),):
        raise BoundsError(f"bounds must have one entry per base vertex ({len(P)})")
    A = P + D * bounds.bias[:, None]
    B = A + D * bounds.scale[:, None]
    a0, a1, a2 = A[f[:, 0]], A[f[:, 1]], A[f[:, 2]]
    b0, b1, b2 = B[f[:, 0]], B[f[:, 1]], B[f[:, 2]]

    def tet(p, q, r, s):
        return np.abs(np.einsum("ij,ij->i", q - p, np.cross(r - p, s - p))) / 6.0

    return tet(a0, a1, a2, b0) + tet(a1, a2, b0, b1) + tet(a2, b0, b1, b2)


def shell_volume(base_vertices: np.ndarray, faces: np.ndarray, directions: np.ndarray,
                 bounds: DirectionBounds) -> float:
    """Sum of :func:`prismoid_volumes`."""
    return float(prismoid_volumes(base_vertices, faces, directions, bounds).sum())


def micromesh_shell_volume(mm: MicroMesh, bounds: DirectionBounds | None = None) -> float:
    """Shell volume of a micro-mesh under its tight bounds (or the given ones)."""
    b = tight_bounds(mm) if bounds is None else bounds
    return shell_volume(mm.base.vertices, mm.base.faces, mm.directions, b)


def unit_bounds(n: int) -> DirectionBounds:
    """Bias 0, scale 1 for ``n`` vertices: the bounds of a :func:`baked` micro-mesh."""
    return DirectionBounds(np.zeros(n), np.ones(n))


def baked(mm: MicroMesh, bounds: DirectionBounds) -> MicroMesh:
    """The micro-mesh with its bounds folded into the base and the directions, as
    micromesh-tools writes its files: base P + D·bias, directions D·scale, each micro-vertex
    the value t in [0, 1] of :func:`normalized_values`. Under bounds that differ from vertex
    to vertex a file cannot say every position of ``mm`` exactly (the interpolated D·scale is
    not parallel to the interpolated D); the baked micro-mesh is what a file holds, and
    :func:`unit_bounds` express it exactly."""
    t = normalized_values(mm, bounds)
    base = mm.base.with_vertices(mm.base.vertices + mm.directions * bounds.bias[:, None])
    return MicroMesh(base, mm.directions * bounds.scale[:, None], mm.levels, t, mm._topology)
