"""Optimiser pieces: Adam with uniform second-moment scaling, gradient clipping, and the
Large Steps reparameterised parameter x = (I + λL)^-1 x̄.

Uniform Adam (Nicolet et al. 2021) divides the first moment by the *maximum* over the tensor
of sqrt(v̂) instead of per-entry, so the preconditioning of the reparameterisation, which a
per-entry Adam would undo, survives: a plain gradient step on x̄ moves x by
-η (I + λL)^-2 ∂Φ/∂x (the supplement's Eq. 2).
"""
from __future__ import annotations

import math
from collections import defaultdict
from typing import Callable, Iterable

import numpy as np
import torch


class UniformAdam:
    """Adam whose denominator is one scalar per tensor: max(sqrt(v̂)) + eps.

    ``params``: tensors, or groups as ``torch.optim`` takes them (dicts with "params" and
    their own "lr", "betas", "eps"). Not a ``torch.optim.Optimizer``: its constructor
    imports torch's graph compiler (about 1.2 s, before a construction's first iteration),
    and nothing here needs it.
    """

    def __init__(self, params, lr: float = 1e-3, betas: tuple[float, float] = (0.9, 0.999),
                 eps: float = 1e-8):
        if lr <= 0:
            raise ValueError("learning rate must be positive")
        params = list(params)
        groups = params if params and isinstance(params[0], dict) else [{"params": params}]
        defaults = dict(lr=lr, betas=tuple(betas), eps=eps)
        self.param_groups = [{**defaults, **g, "params": list(g["params"])} for g in groups]
        self.state: defaultdict[torch.Tensor, dict] = defaultdict(dict)

    def zero_grad(self, set_to_none: bool = True) -> None:
        for group in self.param_groups:
            for p in group["params"]:
                if p.grad is None:
                    continue
                if set_to_none:
                    p.grad = None
                else:
                    p.grad.zero_()

    @torch.no_grad()
    def step(self, closure: Callable | None = None):
        loss = closure() if closure is not None else None
        for group in self.param_groups:
            b1, b2 = group["betas"]
            for p in group["params"]:
                if p.grad is None:
                    continue
                st = self.state[p]
                if not st:
                    st["step"] = 0
                    st["m"] = torch.zeros_like(p)
                    st["v"] = torch.zeros_like(p)
                st["step"] += 1
                t = st["step"]
                g = p.grad
                st["m"].mul_(b1).add_(g, alpha=1 - b1)
                st["v"].mul_(b2).addcmul_(g, g, value=1 - b2)
                denom = (st["v"].max().sqrt() / math.sqrt(1 - b2 ** t)) + group["eps"]
                p.add_(st["m"] / denom, alpha=-group["lr"] / (1 - b1 ** t))
        return loss

    def reset_state(self, param: torch.Tensor) -> None:
        """Forget the moments of one parameter (after it was re-created at a new level)."""
        self.state.pop(param, None)


def clip_gradients(params: Iterable[torch.Tensor], max_norm: float) -> float:
    """Scale each tensor's gradient down to at most ``max_norm`` (2-norm); returns the largest
    norm seen. Per tensor, because base offsets and displacements live on different scales."""
    worst = 0.0
    if max_norm <= 0:
        return worst
    for p in params:
        if p.grad is None:
            continue
        n = float(torch.linalg.vector_norm(p.grad))
        if not math.isfinite(n):
            p.grad.nan_to_num_(0.0, 0.0, 0.0)
            n = float(torch.linalg.vector_norm(p.grad))
        worst = max(worst, n)
        if n > max_norm:
            p.grad.mul_(max_norm / n)
    return worst


class Reparameterized:
    """A geometry tensor x held as x̄ = (I + λL) x; :meth:`value` solves it back (differentiably).

    With ``solver=None`` it is the identity (x̄ = x): the ablation without reparameterisation.
    ``solver`` is a :class:`core.solvers.screened.ScreenedSolver` for (I + λL).
    """

    def __init__(self, value: np.ndarray, solver=None, dtype=torch.float32, device="cpu"):
        self.solver = solver
        self.dtype, self.device = dtype, device
        self.param = torch.nn.Parameter(torch.as_tensor(self.encode(value), dtype=dtype, device=device))

    def encode(self, x: np.ndarray) -> np.ndarray:
        """x̄ = (I + λL) x (or x without a solver)."""
        x = np.asarray(x, dtype=np.float64)
        if self.solver is None:
            return x
        return self.solver.multiply(x)

    def value(self) -> torch.Tensor:
        """x = (I + λL)^-1 x̄ with gradients to x̄."""
        if self.solver is None:
            return self.param
        return self.solver.apply(self.param)

    def numpy(self) -> np.ndarray:
        with torch.no_grad():
            return self.value().detach().cpu().double().numpy()
