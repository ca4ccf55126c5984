"""Area-weighted vertex normal sums on CUDA: each face's cross product added to its three
vertices by ``corner_sums`` (a fixed order, no atomics, no sorting scatter-adds), in the
forward and the backward."""
from __future__ import annotations

import torch

from . import triton_kernels
from .corner_sums import vertex_sums


def _corners(values: torch.Tensor) -> torch.Tensor:
    """(M * 3, 3): each face's row once per corner."""
    return values[:, None, :].expand(-1, 3, -1).reshape(-1, 3)


class _NormalSums(torch.autograd.Function):
    @staticmethod
    def forward(ctx, verts, faces):
        p = verts.detach()[faces]
        a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        out = vertex_sums(faces, _corners(torch.linalg.cross(a, b)), len(verts))
        ctx.stuff = (faces, a, b, len(verts))
        return out.to(verts.dtype)

    @staticmethod
    def backward(ctx, g):
        faces, a, b, n_verts = ctx.stuff
        gf = g[faces]
        k = (gf[:, 0] + gf[:, 1]) + gf[:, 2]
        # cross = a x b: d/da = b x k, d/db = k x a; vertex 0 moves both a and b
        ga, gb = torch.linalg.cross(b, k), torch.linalg.cross(k, a)
        per_corner = torch.stack([-(ga + gb), ga, gb], 1).reshape(-1, 3)
        return vertex_sums(faces, per_corner, n_verts).to(g.dtype), None


def normal_sums(verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor | None:
    """(N, 3) sums of the incident faces' cross products (differentiable w.r.t. verts); None
    where the kernels cannot run."""
    if not triton_kernels.available(verts.device):
        return None
    return _NormalSums.apply(verts, faces.long().contiguous())
