"""A fit round that turns the displacement directions too (ours).

A micro-vertex sits at X_k = P_k + D_k d_k with D_k = Σ_j W_kj Dir_j, the base directions
interpolated. One displacement per micro-vertex moves it only along D_k, so the directions
decide where on the reference the micro-vertices can land: at a crease, where a base vertex's
direction is the mean of its faces' normals, they cannot reach the crease line. X_k is
bilinear in (d, Dir); linearised where the round starts (d⁰, Dir⁰), an increment ΔDir_j moves
micro-vertex k by d⁰_k W_kj ΔDir_j. That is the base round's system (``joint_sums``: a base
offset moves it by W_kj Δ_j) with W scaled row by row by d⁰, so the same compiled sums serve:
one Gauss-Newton step over the displacements and the direction increments together.

Safeguards:
- Marquardt damping: each direction is held by ``damping`` times its own curvature (the trace
  of its 3 x 3 block), so the step is scale-free: a base vertex whose micro-vertices hardly
  leave the base barely turns its direction, however the samples pull.
- A micro-vertex that no sample holds (``system.unheld_vertices``) is held where it is, as a
  position (``hold`` of the median vertex's hold): turning a direction would otherwise swing
  it out with nothing to bring it back (an ogre's toe grew a spike).
- A direction turned past 90° from where it was is put back (thin parts, pulled from both
  sides, flipped some), and so is one whose micro-vertices then span more than ``WIDENING``
  times the length they did along it: its share of the shell (a flight helmet's thin
  straps: the whole round widened the shell by half; ``core.construct.fitting`` fits the
  displacements once more after it).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..micro.bounds import reach
from ..micro.micromesh import MicroMesh
from .joint_sums import joint_system
from .samples import CHUNK, Samples
from .solve import solve_normal_equations
from .system import regularisation, sample_matches, sorted_csr, unheld_vertices

DAMPING = 0.1
HOLD = 0.03
WIDENING = 1.1
# CG steps of the round's solve, converged or not (it starts from the fitted displacements).
STEPS = 30


def fit_directions(mm: MicroMesh, samples: Samples, smoothness: float = 1e-3,
                   slopes: float = 0.1, damping: float = DAMPING, hold: float = HOLD
                   ) -> MicroMesh:
    """``mm`` after one round over its displacements and base directions (its base kept);
    the fit's ``smoothness`` and ``slopes`` as in ``fit_micromesh``. The directions come back
    unnormalised, as the format interpolates them."""
    W = mm.topology.interp.tocsr()
    n, nb = mm.n_vertices, mm.base.n_vertices
    d = mm.displacements
    P, D = W @ mm.base.vertices, mm.micro_vertex_directions()
    T = mm.topology.triangles
    Wd = sp.csr_matrix((W.data * np.repeat(d, np.diff(W.indptr)), W.indices, W.indptr),
                       shape=W.shape)
    matches = sample_matches(P + D * d[:, None], mm.topology, samples, CHUNK)
    M, b = joint_system(matches, T, P, D, Wd, mm.topology, mm.base.faces, slopes)
    M, b = _held(M, b, Wd, D, d, hold)
    size = M.shape[0]
    damp = np.zeros(size)
    damp[n:] = np.tile(_damping(M.diagonal()[n:].reshape(3, nb), damping), 3)
    b[:n] += 1e-9 * d
    M = sorted_csr(M + regularisation(T, D, smoothness, size) + sp.diags(damp, format="csr"))
    x = solve_normal_equations(M, b, np.concatenate([d, np.zeros(3 * nb)]), maxiter=STEPS,
                               blocks=nb, exact=False)
    turned = mm.directions + x[n:].reshape(3, nb).T
    before = reach(mm)
    widened = reach(MicroMesh(mm.base, turned, mm.levels, x[:n], mm.topology)) > \
        WIDENING * before + 1e-12 * before.max(initial=0.0)
    back = widened | ((turned * mm.directions).sum(1) <= 0)
    return MicroMesh(mm.base, np.where(back[:, None], mm.directions, turned), mm.levels, x[:n],
                     mm.topology)


def _damping(diag: np.ndarray, damping: float) -> np.ndarray:
    """Per base vertex (nb,): ``damping`` times the trace of its direction's block (``diag``
    (3, nb): its three diagonal entries), the same for every axis, whatever the frame (a flat
    region's samples all share one normal, so two axes may have none), and where a direction
    has no influence at all a floor that keeps the system definite."""
    lam = damping * diag.sum(0)
    live = lam[lam > 0]
    return np.maximum(lam, 1e-6 * float(np.median(live)) if len(live) else 1.0)


def _held(M: sp.csr_matrix, b: np.ndarray, Wd: sp.csr_matrix, D: np.ndarray, d: np.ndarray,
          hold: float) -> tuple[sp.csr_matrix, np.ndarray]:
    """The system with each micro-vertex no sample holds kept at its position: three rows
    per such vertex k, D_k d_k + d⁰_k Σ_j W_kj ΔDir_j = D_k d⁰_k, weighted ``hold`` times the
    median vertex's hold."""
    unheld, firm = unheld_vertices(M.diagonal(), D)
    if not len(unheld) or hold <= 0:
        return M, b
    n, nb = len(D), Wd.shape[1]
    sub = Wd[unheld].tocoo()
    rows, cols, vals = [], [], []
    for a in range(3):
        rows += [3 * np.arange(len(unheld)) + a, 3 * sub.row + a]
        cols += [unheld, n + a * nb + sub.col]
        vals += [D[unheld, a], sub.data]
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(3 * len(unheld), M.shape[0]))
    w = hold * firm
    return M + w * (A.T @ A).tocsr(), b + w * (A.T @ (D[unheld] * d[unheld, None]).reshape(-1))
