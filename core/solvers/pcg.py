"""Jacobi-preconditioned conjugate gradient in torch, on whatever device the tensors live."""
from __future__ import annotations


def pcg_torch(matvec, inv_diag, b, x0=None, *, tol: float = 1e-10, maxiter: int = 1000,
              check_every: int = 1):
    """Jacobi-preconditioned CG for SPD systems, all columns of ``b`` (n,) or (n, k) at once.

    Stops when every column's residual is below ``tol`` times its right-hand side norm.
    Returns ``(x, iterations)``.
    """
    import torch

    vec = b.ndim == 1
    if vec:
        b = b[:, None]
        x0 = None if x0 is None else x0[:, None]
    dinv = inv_diag[:, None]
    bnorm = torch.linalg.vector_norm(b, dim=0)
    if x0 is not None:
        x = torch.where(bnorm > 0, x0, 0.0)  # a zero column's solution is exactly zero
        r = b - matvec(x)
    else:
        x, r = torch.zeros_like(b), b.clone()
    thresh = (tol * bnorm) ** 2
    z = dinv * r
    p = z.clone()
    rz = (r * z).sum(0)
    it = 0
    tiny = torch.finfo(b.dtype).tiny
    while it < maxiter:
        if it % check_every == 0 and bool(((r * r).sum(0) <= thresh).all()):
            break
        Ap = matvec(p)
        pAp = (p * Ap).sum(0)
        alpha = torch.where(pAp.abs() > tiny, rz / torch.where(pAp.abs() > tiny, pAp, 1.0), 0.0)
        x.add_(alpha * p)
        r.sub_(alpha * Ap)
        z = dinv * r
        rz_new = (r * z).sum(0)
        beta = torch.where(rz.abs() > tiny, rz_new / torch.where(rz.abs() > tiny, rz, 1.0), 0.0)
        p = z + beta * p
        rz = rz_new
        it += 1
    return (x[:, 0] if vec else x), it
