"""CPU backend: the numba rasteriser and fused per-pixel kernels wrapped as autograd Functions.

``render_numba`` = vertex normals (torch, O(N + M), autograd) -> fused shade kernel (analytic
backward) -> antialias kernel (analytic backward). The L1 loss is reduced in torch on top.
"""
from __future__ import annotations

import numpy as np
import torch

from . import antialias as aa
from . import shade as sk
from .normals import vertex_normals_numba
from .raster import edge_flags_numba, rasterize_numba
from .sh import SH_QUADRATIC
from .topology import faces_int32
from .types import Raster

__all__ = ["rasterize_numba", "render_numba", "loss_numba"]

_QA, _QB, _QK = (np.ascontiguousarray(a, dtype=np.float64) for a in SH_QUADRATIC)


def _np(t: torch.Tensor) -> np.ndarray:
    return t.detach().contiguous().numpy()


def _faces_np(faces: torch.Tensor) -> np.ndarray:
    return faces_int32(faces)


class _Shade(torch.autograd.Function):
    @staticmethod
    def forward(ctx, verts, vnormals, faces, mvp, tri, mode: int):
        v, f, m, t = _np(verts), _faces_np(faces), _np(mvp), _np(tri)
        vn = _np(vnormals) if vnormals is not None else np.zeros((1, 3), v.dtype)
        nc = 3 if mode in (sk.MODE_SHADED, sk.MODE_NORMAL) else 1
        out = np.zeros(t.shape + (nc,), dtype=v.dtype)
        sk.shade_forward(v, f, vn, m, t, mode, _QA, _QB, _QK, out)
        ctx.save_for_backward(verts, vnormals if vnormals is not None else verts)
        ctx.stuff = (faces, mvp, tri, mode, vnormals is not None)
        return torch.from_numpy(out)

    @staticmethod
    def backward(ctx, gout):
        verts, vnormals = ctx.saved_tensors
        faces, mvp, tri, mode, has_vn = ctx.stuff
        if mode == sk.MODE_MASK:
            return None, None, None, None, None, None
        v = _np(verts)
        vn = _np(vnormals) if has_vn else np.zeros((1, 3), v.dtype)
        gv = np.zeros((sk.SLOTS,) + v.shape, dtype=v.dtype)
        gn = np.zeros((sk.SLOTS,) + vn.shape, dtype=v.dtype)
        g = _np(gout.to(verts.dtype))
        sk.shade_backward(v, _faces_np(faces), vn, _np(mvp), _np(tri), mode, _QA, _QB, _QK, g, gv, gn)
        gverts = torch.from_numpy(gv).sum(0)
        gvn = torch.from_numpy(gn).sum(0) if has_vn else None
        return gverts, gvn, None, None, None, None


class _Antialias(torch.autograd.Function):
    @staticmethod
    def forward(ctx, color, verts, faces, flags, mvp, tri, depth):
        c, v, f, m, t = _np(color), _np(verts), _faces_np(faces), _np(mvp), _np(tri)
        code_h = np.empty(t.shape, np.int32)
        code_v = np.empty(t.shape, np.int32)
        aa.pair_codes(v, f, m, t, _np(depth), flags, code_h, code_v)
        out = np.empty_like(c)
        aa.antialias_forward(c, v, f, m, code_h, code_v, out)
        ctx.save_for_backward(color, verts)
        ctx.stuff = (faces, mvp, code_h, code_v)
        return torch.from_numpy(out)

    @staticmethod
    def backward(ctx, gout):
        color, verts = ctx.saved_tensors
        faces, mvp, code_h, code_v = ctx.stuff
        c = _np(color)
        v = _np(verts)
        gcolor = np.empty_like(c)
        gv = np.zeros((sk.SLOTS,) + v.shape, dtype=v.dtype)
        aa.antialias_backward(c, v, _faces_np(faces), _np(mvp), code_h, code_v,
                              _np(gout.to(color.dtype)), gcolor, gv)
        return torch.from_numpy(gcolor), torch.from_numpy(gv).sum(0), None, None, None, None, None


def shade_numba(verts: torch.Tensor, faces: torch.Tensor, raster: Raster, kind: str) -> torch.Tensor:
    """(B, H, W, C) un-antialiased image of ``kind`` (differentiable w.r.t. verts)."""
    mode = sk.MODES[kind]
    vn = vertex_normals_numba(verts, faces) if mode in (sk.MODE_SHADED, sk.MODE_NORMAL) else None
    return _Shade.apply(verts, vn, faces, raster.mvp, raster.tri_id, mode)


def antialias_numba(color: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor,
                    raster: Raster) -> torch.Tensor:
    """Analytic antialiasing of ``color`` (B, H, W, C), differentiable w.r.t. color and verts."""
    flags = raster.edge_flags
    flags = flags.numpy() if flags is not None else edge_flags_numba(verts, faces, raster.mvp, raster.tri_id)
    return _Antialias.apply(color.to(verts.dtype), verts, faces, flags, raster.mvp, raster.tri_id,
                            raster.depth)


def render_numba(verts: torch.Tensor, faces: torch.Tensor, raster: Raster, kind: str,
                 antialias: bool) -> torch.Tensor:
    img = shade_numba(verts, faces, raster, kind)
    return antialias_numba(img, verts, faces, raster) if antialias else img


def loss_numba(verts, faces, raster, target, antialias):
    img = render_numba(verts, faces, raster, "shaded", antialias)
    return (img - target.to(img.dtype)).abs().mean()
