"""The torch path's shading ("shaded" and "flat") as one autograd op on fused Triton kernels
(``triton_shade``, ``triton_shade_grad``): no per-pixel gathers or scatters through torch, and a backward that adds
every pixel's and corner's part in a fixed order (the same gradient on every run).

``shade`` returns None where the kernels cannot run (no Triton, not CUDA, a compiler or driver
error): the caller then runs the plain torch code, which stays the reference.
"""
from __future__ import annotations

import numpy as np
import torch

from . import triton_kernels, triton_shade, triton_shade_grad
from .corner_sums import segments, vertex_sums
from .sh import SH_QUADRATIC
from .triton_kernels import BLOCK_SIZE, guarded, triton

_Q: dict = {}


class _Unavailable(Exception):
    """A kernel failed (``triton_kernels.failure`` says why)."""


def _quadratic(device: torch.device) -> torch.Tensor:
    """(30,) float64: per channel [k, b (3), a00, a11, a22, a01, a02, a12] of the lighting."""
    if device not in _Q:
        a, b, k = SH_QUADRATIC
        rows = [np.r_[k[c], b[c], a[c, 0, 0], a[c, 1, 1], a[c, 2, 2], a[c, 0, 1], a[c, 0, 2],
                      a[c, 1, 2]] for c in range(3)]
        _Q[device] = torch.tensor(np.concatenate(rows), dtype=torch.float64, device=device)
    return _Q[device]


@guarded
def _forward(verts, vn, faces, mvp16, tri, flat: bool, width: int, height: int):
    out = torch.empty((tri.numel(), 3), dtype=verts.dtype, device=verts.device)
    if tri.numel():
        grid = (triton.cdiv(tri.numel(), BLOCK_SIZE),)
        triton_shade.shade_forward_kernel[grid](
            verts, vn, faces, mvp16, tri, _quadratic(verts.device), out, tri.numel(), width,
            height, FLAT=flat, BLOCK=BLOCK_SIZE)
    return out


@guarded
def _backward(verts, vn, faces, mvp16, tri, gout, flat: bool, width: int, height: int):
    """(N, 6) float64: d(sum gout * image) / d (vertex, vertex normal)."""
    n_faces, n_verts, dev = len(faces), len(verts), verts.device
    order, start, count = segments(tri, n_faces)
    fg = torch.empty((n_faces * 3, 6), dtype=torch.float64, device=dev)
    if n_faces:
        triton_shade_grad.shade_backward_kernel[(triton.cdiv(n_faces, BLOCK_SIZE),)](
            verts, vn, faces, mvp16, order, start, count, gout, _quadratic(dev), fg, n_faces,
            width, height, FLAT=flat, BLOCK=BLOCK_SIZE)
    return vertex_sums(faces, fg, n_verts)


class _Shade(torch.autograd.Function):
    @staticmethod
    def forward(ctx, verts, vn, faces, mvp, tri_id, flat, plain):
        nb, height, width = tri_id.shape
        v = verts.detach().contiguous()
        n = v if vn is None else vn.detach().to(v.dtype).contiguous()
        f, m, t = faces.long().contiguous(), mvp.reshape(-1, 16).to(torch.float64).contiguous(), \
            tri_id.reshape(-1).contiguous()
        out = _forward(v, n, f, m, t, flat, width, height)
        if out is None:
            raise _Unavailable(triton_kernels.failure)
        ctx.stuff = (v, n, f, m, t, flat, width, height, vn is not None)
        ctx.plain = plain
        return out.view(nb, height, width, 3)

    @staticmethod
    def backward(ctx, gout):
        v, n, f, m, t, flat, width, height, has_vn = ctx.stuff
        g = _backward(v, n, f, m, t, gout.contiguous(), flat, width, height)
        if g is None:
            if ctx.plain is None:
                raise RuntimeError(f"the shading backward kernel failed: {triton_kernels.failure}")
            return _plain_backward(ctx, gout) + (None, None, None, None, None)
        g = g.to(v.dtype)
        return g[:, :3], (g[:, 3:] if has_vn else None), None, None, None, None, None


def _plain_backward(ctx, gout):
    """The plain path's gradient (``ctx.plain``), where the backward kernel failed after the
    forward ran."""
    v, n, f, m, t, flat, width, height, has_vn = ctx.stuff
    with torch.enable_grad():
        x = v.clone().requires_grad_(True)
        vn = n.clone().requires_grad_(True) if has_vn else None
        img = ctx.plain(x, f, vn, m.view(-1, 4, 4), t.view(-1, height, width),
                        "flat" if flat else "shaded")
        grads = torch.autograd.grad(img, [x] + ([vn] if has_vn else []), gout)
    return grads[0], (grads[1] if has_vn else None)


def shade(verts: torch.Tensor, faces: torch.Tensor, vnormals: torch.Tensor | None,
          mvp: torch.Tensor, tri_id: torch.Tensor, kind: str, plain=None) -> torch.Tensor | None:
    """(B, H, W, 3) "shaded" (needs ``vnormals``) or "flat" image, background 0,
    differentiable w.r.t. verts and vnormals; None where the kernels cannot run.
    ``plain(verts, faces, vnormals, mvp, tri_id, kind)``: the same image without these
    kernels, whose gradient is used where the backward kernel fails after the forward ran
    (without it that failure raises)."""
    if not triton_kernels.available(verts.device) or kind not in ("shaded", "flat"):
        return None
    try:
        return _Shade.apply(verts, vnormals, faces, mvp, tri_id, kind == "flat", plain)
    except _Unavailable:
        return None
