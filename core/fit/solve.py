"""The fit's sparse symmetric positive definite solve."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def solve_normal_equations(M: sp.csr_matrix, b: np.ndarray, x0: np.ndarray,
                           rtol: float = 1e-8, maxiter: int = 2000, callback=None,
                           blocks: int = 0, exact: bool = True) -> np.ndarray:
    """x with M x = b (M symmetric positive definite): conjugate gradients from ``x0`` (the
    fit starts close to its answer: tens of iterations, 20-45 times faster than a
    factorisation at 40k-100k unknowns, ``bench/fit_bench.py``); a sparse factorisation where
    CG does not converge. ``callback``: called after each CG iteration. At ``rtol`` 1e-8 the
    answer stands within 2e-4 of an 11-bit quantisation step from a far tighter solve's
    (igea_269k's micro-mesh: 1184 iterations instead of 1446 at 1e-10). ``exact`` False: the
    CG iterate after ``maxiter`` is the answer, converged or not (each CG step lowers the
    quadratic energy, so it is an improvement on ``x0``; for the base round, whose system
    converges slowly).

    The preconditioner is Jacobi's, except for the last 3 ``blocks`` unknowns (the base
    vertices' x, y, z, in that order): there the 3 x 3 block of each vertex is inverted, since
    a vertex's coordinates are coupled through the normals of the rows that see it.
    """
    diag = M.diagonal()
    if not (diag > 0).all():
        return spla.spsolve(M.tocsc(), b)
    n = len(b) - 3 * blocks
    inv_diag = 1.0 / diag[:n]
    if blocks:
        tail = M[n:, n:]
        B = np.empty((blocks, 3, 3))
        for a in range(3):
            for c in range(3):
                B[:, a, c] = tail[a * blocks:(a + 1) * blocks, c * blocks:(c + 1) * blocks].diagonal()
        inv_blocks = np.linalg.inv(B)

    def precondition(r):
        r = np.asarray(r).reshape(-1)
        z = np.empty_like(r)
        z[:n] = inv_diag * r[:n]
        if blocks:
            z[n:] = np.einsum("jac,jc->ja", inv_blocks, r[n:].reshape(3, blocks).T).T.reshape(-1)
        return z

    P = spla.LinearOperator(M.shape, matvec=precondition, dtype=np.float64)
    x, info = spla.cg(M, b, x0=x0, rtol=rtol, maxiter=maxiter, M=P, callback=callback)
    if (info == 0 or not exact) and np.isfinite(x).all():
        return x
    return spla.spsolve(M.tocsc(), b)
