"""Row gathers and scatter-adds that give the same sums on every run.

On CUDA the plain ops add colliding rows with atomics in thread order; these add them in a
fixed order (``core.runtime.determinism``), in the forward and in the backward. On the CPU
they are the plain ops.
"""
from __future__ import annotations

import torch

from ..runtime.determinism import deterministic


def scatter_add(out: torch.Tensor, index: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    """``out`` with ``values`` (K, ...) added to rows ``index`` (K,) (a new tensor;
    differentiable w.r.t. ``out`` and ``values``)."""
    if out.device.type != "cuda":
        return out.index_add(0, index, values)
    with deterministic(out.device):
        return out.index_put((index,), values, accumulate=True)


class _Gather(torch.autograd.Function):
    @staticmethod
    def forward(ctx, src, index):
        ctx.save_for_backward(index)
        ctx.shape = src.shape
        return src[index]

    @staticmethod
    def backward(ctx, grad):
        (index,) = ctx.saved_tensors
        out = torch.zeros(ctx.shape, dtype=grad.dtype, device=grad.device)
        with deterministic(grad.device):
            return out.index_put_((index.reshape(-1),), grad.reshape(-1, *ctx.shape[1:]),
                                  accumulate=True), None


def gather(src: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """``src[index]`` (index of any shape, into src's first axis) whose backward adds colliding
    rows in a fixed order on CUDA."""
    if src.device.type != "cuda" or not src.requires_grad:
        return src[index]
    return _Gather.apply(src, index)
