"""The normal equations of one fit round: samples matched to the micro-surface, the
point-to-plane and slope rows, the micro-vertices no sample holds kept where they are, the
smoothness term, and the base vertices as unknowns too.

Every row is a residual n · (Σ_k c_k X_k) − t along one sample's normal n, over micro-vertex
positions X_k = Σ_j W_kj V_j + D_k d_k (``W``: the topology's interpolation of the base
vertices V): a point row has the barycentrics of the sample's closest point as c and n·s as
t; a slope row has −1 and +1 at the ends of one edge of the matched micro-triangle and t = 0.
So a row is linear in the displacements d (coefficients c_k n·D_k) and in the base vertices
(coefficients n_a (C W)_j for coordinate a).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..spatial.barycentric import barycentrics
from ..spatial.closest import index_on
from ..solvers.laplacian import uniform_laplacian
from ..micro.micromesh import MicroMesh
from .joint_sums import joint_system
from .rows import row_system
from .samples import CHUNK, Samples
from .triangle_sums import BlockOperator, blocks_csr, f64, triangle_sums


def normal_equations(mm: MicroMesh, d: np.ndarray, samples: Samples, smoothness: float,
                     slopes: float, base_stiffness: float = 0.0,
                     offsets: np.ndarray | None = None, chunk: int = CHUNK, by_rows: bool = False,
                     fixed: np.ndarray | None = None) -> tuple[sp.csr_matrix, np.ndarray]:
    """(M, b) of one fit round: the samples matched to their closest points on the
    micro-surface of displacements ``d`` (and base vertices moved by ``offsets`` (nb, 3)),
    then the weighted least-squares system.

    Unknowns: the displacements (n,); with ``base_stiffness`` > 0 also increments of the base
    offsets (3 nb, x then y then z), held by ``base_stiffness`` · (weight per base vertex) ·
    |offsets|². M is (n, n) or (n + 3 nb, n + 3 nb). ``fixed`` (nb,) bool: base vertices
    that do not move (their increments' rows and columns are the identity's, b's rows 0).

    The system is summed in one compiled pass over the samples: per micro-triangle over the
    displacements alone (:mod:`.triangle_sums`), with the base also per (micro-vertex, base
    face) pair and per base face (:mod:`.joint_sums`). ``by_rows``: from the rows themselves
    (the general way, which the tests and ``bench/fit_bench.py`` compare them with; the rows
    of all samples at once took 6 KB per sample at the peak). Either way the samples are
    made, matched and summed ``chunk`` at a time (:data:`.samples.CHUNK`), in order (the same
    sums as all at once): the matches of all samples together (closest points, triangles,
    corners, barycentrics and the corners' positions, about 170 bytes a sample) were the
    fit's peak on large inputs.
    """
    W = mm.topology.interp.tocsr()
    n, nb = mm.n_vertices, mm.base.n_vertices
    offsets = np.zeros((nb, 3)) if offsets is None else offsets
    P, D = W @ (mm.base.vertices + offsets), mm.micro_vertex_directions()
    T = mm.topology.triangles                  # the non-degenerate micro-triangles
    matches = sample_matches(P + D * d[:, None], mm.topology, samples, chunk)
    joint = base_stiffness > 0
    if by_rows:
        M, b = row_system(matches, P, D, W if joint else None, n + 3 * nb if joint else n,
                          slopes)
    elif joint:
        M, b = joint_system(matches, T, P, D, W, mm.topology, mm.base.faces, slopes)
    else:
        M, b = _unheld_kept(*_displacement_system(matches, T, P, D, slopes), D, d)
    b[:n] += 1e-9 * d
    R = regularisation(T, D, smoothness, M.shape[0])
    if not joint:
        return sorted_csr(M + R), b
    size = M.shape[0]
    k = base_stiffness * samples.weights.sum() * (1 + (3 * slopes if slopes > 0 else 0)) / nb
    stiff = np.zeros(size)
    stiff[n:] = k
    b[n:] -= k * offsets.T.reshape(-1)                # holds the offsets, not the increments
    M = M + R + sp.diags(stiff, format="csr")
    if fixed is not None and fixed.any():
        still = np.concatenate([np.zeros(n, bool), np.tile(fixed, 3)])
        keep = sp.diags((~still).astype(np.float64), format="csr")
        M = keep @ M @ keep + sp.diags(still.astype(np.float64), format="csr")
        b[still] = 0.0
    return sorted_csr(M), b


# A micro-vertex is unheld where its samples' share of the normal equations' diagonal is below
# this fraction of the median vertex's: no sample matched any micro-triangle around it.
_UNHELD = 1e-3
# How firmly an unheld micro-vertex is kept at its displacement, as a fraction of the median
# vertex's hold by its samples (docs/results.md, thirteenth session).
_KEEP = 0.03


def regularisation(T: np.ndarray, D: np.ndarray, smoothness: float, size: int
                   ) -> sp.csr_matrix:
    """The smoothness of the displacement as a length (|D_k| d_k: the same weight whether
    the directions are unit or scaled by folded bounds, ``core.micro.bounds.baked``) and 1e-9 I,
    over the first n = len(D) unknowns of a ``size``-unknown system (padded in CSR: a
    block_diag goes through triplets, as large as the system at a million unknowns)."""
    n = len(D)
    if smoothness > 0:
        LS = (uniform_laplacian(n, T) @ sp.diags(np.linalg.norm(D, axis=1))).tocsr()
        R = (smoothness * (LS.T.tocsr() @ LS) + 1e-9 * sp.eye(n, format="csr")).tocsr()
    else:         # (LᵀL at a million unknowns is the round's largest matrix: not made for 0)
        R = 1e-9 * sp.eye(n, format="csr")
    return sp.csr_matrix((R.data, R.indices, np.concatenate(
        [R.indptr, np.full(size - n, R.indptr[-1])])), shape=(size, size))


def unheld_vertices(diag: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, float]:
    """(the micro-vertices no sample holds, the median vertex's hold): from the diagonal of
    the displacements' system (``diag`` (n,) at least), those whose samples' share is below
    ``_UNHELD`` of the median's, among those with a direction."""
    diag = diag[:len(D)]
    held = diag[diag > 0]
    if not len(held):
        return np.zeros(0, np.int64), 0.0
    firm = float(np.median(held))
    return np.flatnonzero((diag < _UNHELD * firm) & ((D * D).sum(1) > 0)), firm


def _unheld_kept(M: sp.csr_matrix, b: np.ndarray, D: np.ndarray, d: np.ndarray
                 ) -> tuple[sp.csr_matrix, np.ndarray]:
    """The displacements' system with each micro-vertex that no sample holds kept, weakly, at
    its displacement ``d``. The fit matches each reference sample to its closest micro-triangle,
    so a patch of micro-surface off the reference gets no samples; the smoothness alone let it
    drift into spikes that set the shell (a CAD part's bolt holes). The base's round does
    without it (it cost there more than it gave)."""
    unheld, firm = unheld_vertices(M.diagonal(), D)
    if not len(unheld):
        return M, b
    extra = np.zeros(len(d))
    extra[unheld] = _KEEP * firm
    b = b.copy()
    b[unheld] += _KEEP * firm * d[unheld]
    return M + sp.diags(extra, format="csr"), b


def sorted_csr(M) -> sp.csr_matrix:
    """``M`` as CSR with each row's columns in order (the solver's products then sum in one
    order whichever way the system was added up)."""
    M = M.tocsr()
    M.sort_indices()
    return M


def sample_matches(X: np.ndarray, topology, samples: Samples, chunk: int):
    """Per about ``chunk`` samples in order: (points (c, 3), normals (c, 3), weights (c,),
    matched micro-triangles (c,), their corners (c, 3), the closest points' barycentrics
    (c, 3)) on the micro-surface of micro-vertices ``X`` and ``topology``'s triangles (their
    index: ``core.spatial.closest.index_on``, one tree per topology, refitted round by round)."""
    T = topology.triangles
    index = index_on(X, T, topology)
    for _, pts, normals, weights in samples.chunks(chunk):
        cp, tri, _ = index.query(pts)
        corners = np.ascontiguousarray(T[tri], dtype=np.int64)
        yield pts, normals, weights, tri, corners, barycentrics(cp, X[corners])


def _displacement_system(matches, T, P, D, slopes):
    """(M, b) over the displacements alone: each micro-triangle's 3 x 3 block, summed over its
    samples by :func:`triangle_sums`, scattered into M (``rows.row_system`` without ``W`` gives
    the same system from the rows)."""
    G, b = _blocks(matches, T, P, D, slopes)
    return blocks_csr(G, T, len(P)), b


def _blocks(matches, T, P, D, slopes, dtype=np.float64) -> tuple[np.ndarray, np.ndarray]:
    """(G (m, 3, 3) of ``dtype``: each micro-triangle's block, its upper triangle summed over
    its samples by :func:`triangle_sums`; b (n,))."""
    G = np.zeros((len(T), 3, 3), dtype)
    b = np.zeros(len(P))
    P, D = f64(P), f64(D)
    for pts, normals, weights, tri, corners, B in matches:
        triangle_sums(tri, corners, B, f64(pts), f64(normals), f64(weights), P, D,
                      float(slopes), G, b)
    return G, b


def displacement_blocks(matches, T: np.ndarray, P: np.ndarray, D: np.ndarray, d: np.ndarray,
                        slopes: float) -> tuple[BlockOperator, np.ndarray]:
    """The displacement round of :func:`normal_equations` without its smoothness (M, b), M
    left as its micro-triangles' blocks (:class:`BlockOperator`: M v without a matrix, a
    tenth of a CSR's memory while it is made), for a solver over other unknowns that M is a
    part of (a height map's texels, ``core.maps.height_fit``): ``matches`` as
    :func:`sample_matches` (or ``grouped.GroupedMatches``) yields them on the triangles
    ``T`` (m, 3) over micro-vertices ``P + D d``. The micro-vertices no sample holds are kept
    where they are, as there. The blocks are float32 (half the memory; each sums a few
    samples, to a relative 1e-7, where the solver stops at 1e-4)."""
    G, b = _blocks(matches, T, P, D, slopes, np.float32)
    M = BlockOperator(G, T, np.full(len(d), 1e-9))
    unheld, firm = unheld_vertices(M.diagonal(), D)
    M.hold[unheld] += _KEEP * firm
    b[unheld] += _KEEP * firm * d[unheld]
    b += 1e-9 * d
    return M, b


