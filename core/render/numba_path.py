"""CPU backend: the numba rasteriser and fused per-pixel kernels wrapped as autograd Functions.

``render_numba`` = vertex normals (numba, analytic backward) -> fused shade kernel (analytic
backward) -> antialias kernel (analytic backward). ``loss_numba`` fuses the L1 loss into the
antialias pass (or a single L1 pass without antialiasing): the image never goes through torch,
and the backward reads an int8 sign image.
"""
from __future__ import annotations

import numpy as np
import torch

from ..runtime.threads import parallel_for
from . import antialias as aa
from . import shade as sk
from . import silhouette, slots
from .numba_geometry import edge_flags_numba, rasterize_numba, vertex_normals_numba
from .sh import SH_QUADRATIC
from .topology import face_neighbours_int32, faces_int32
from .types import Raster

__all__ = ["rasterize_numba", "render_numba", "loss_numba", "shade_numba", "antialias_numba"]

_QA, _QB, _QK = (np.ascontiguousarray(a, dtype=np.float64) for a in SH_QUADRATIC)


def _np(t: torch.Tensor) -> np.ndarray:
    return t.detach().contiguous().numpy()


class _Shade(torch.autograd.Function):
    """Fused per-pixel shading; positions and normals travel packed as one (N, 6) array."""

    @staticmethod
    def forward(ctx, verts, vnormals, faces, mvp, tri, mode: int):
        v, f, m, t = _np(verts), faces_int32(faces), _np(mvp), _np(tri)
        has_vn = vnormals is not None
        pv = np.concatenate([v, _np(vnormals).astype(v.dtype)], axis=1) if has_vn else v
        nc = 3 if mode in (sk.MODE_SHADED, sk.MODE_NORMAL, sk.MODE_FLAT) else 1
        out = np.zeros(t.shape + (nc,), dtype=v.dtype)
        parallel_for(sk.shade_forward, t.shape[0] * t.shape[1], pv, f, pv, 3 if has_vn else 0, m, t,
                     mode, _QA, _QB, _QK, out)
        ctx.pv = pv
        ctx.stuff = (faces, mvp, tri, mode, has_vn, verts.dtype)
        return torch.from_numpy(out)

    @staticmethod
    def backward(ctx, gout):
        faces, mvp, tri, mode, has_vn, dtype = ctx.stuff
        if mode == sk.MODE_MASK:
            return None, None, None, None, None, None
        pv = ctx.pv
        width = 6 if has_vn else 3
        g = slots.slot_buffer("shade", len(pv), pv.dtype, width)
        parallel_for(sk.shade_backward, len(g), pv, faces_int32(faces), pv, 3 if has_vn else 0, _np(mvp),
                     _np(tri), mode, _QA, _QB, _QK, _np(gout.to(dtype)), g, g, parts=len(g))
        total = torch.from_numpy(slots.reduce(g))
        return total[:, :3], (total[:, 3:] if has_vn else None), None, None, None, None


def _codes(verts: np.ndarray, f: np.ndarray, m: np.ndarray, raster: Raster, vt: torch.Tensor,
           faces: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
    t = _np(raster.tri_id)
    flags = raster.edge_flags
    flags = flags.numpy() if flags is not None else edge_flags_numba(vt, faces, raster.mvp, raster.tri_id)
    code_h = np.empty(t.shape, np.int32)
    code_v = np.empty(t.shape, np.int32)
    parallel_for(silhouette.pair_codes, t.shape[0] * t.shape[1], verts, f, face_neighbours_int32(faces), m, t,
                 _np(raster.depth), flags, code_h, code_v)
    return code_h, code_v


class _Antialias(torch.autograd.Function):
    """Antialiased image, or with a target the fused mean L1 loss of the antialiased image."""

    @staticmethod
    def forward(ctx, color, verts, faces, raster, target):
        c, v, f, m = _np(color), _np(verts), faces_int32(faces), _np(raster.mvp)
        code_h, code_v = _codes(v, f, m, raster, verts, faces)
        fuse = target is not None
        out = c[:1, :1] if fuse else np.empty_like(c)
        tg = _np(target.to(color.dtype)) if fuse else c[:1, :1, :1, :1]
        sign = np.empty(c.shape, np.int8) if fuse else np.zeros((1, 1, 1, 1), np.int8)
        rowsum = np.zeros(c.shape[0] * c.shape[1])
        parallel_for(aa.antialias_forward, len(rowsum), c, v, f, m, code_h, code_v, out, tg, sign,
                     rowsum, fuse)
        ctx.save_for_backward(color, verts)
        ctx.stuff = (faces, m, code_h, code_v, sign if fuse else None, c.size)
        if fuse:
            return torch.tensor(rowsum.sum() / c.size, dtype=color.dtype)
        return torch.from_numpy(out)

    @staticmethod
    def backward(ctx, gout):
        color, verts = ctx.saved_tensors
        faces, m, code_h, code_v, sign, count = ctx.stuff
        c, v = _np(color), _np(verts)
        gcolor = np.empty_like(c)
        gv = slots.slot_buffer("aa_v", len(v), v.dtype)
        if sign is not None:
            g, scale = sign, float(gout) / count
        else:
            g, scale = _np(gout.to(color.dtype)), 1.0
        parallel_for(aa.antialias_backward, len(gv), c, v, faces_int32(faces), m, code_h, code_v, g, scale,
                     gcolor, gv, parts=len(gv))
        return torch.from_numpy(gcolor), torch.from_numpy(slots.reduce(gv)), None, None, None


class _L1(torch.autograd.Function):
    """Mean |img - target| with an int8 sign image for the backward."""

    @staticmethod
    def forward(ctx, img, target):
        a, t = _np(img), _np(target.to(img.dtype))
        sign = np.empty(a.shape, np.int8)
        rowsum = np.zeros(a.shape[0] * a.shape[1])
        parallel_for(aa.l1_forward, len(rowsum), a, t, sign, rowsum)
        ctx.stuff = (sign, a.size)
        return torch.tensor(rowsum.sum() / a.size, dtype=img.dtype)

    @staticmethod
    def backward(ctx, gout):
        sign, count = ctx.stuff
        return torch.from_numpy(sign).to(gout.dtype) * (gout / count), None


def shade_numba(verts: torch.Tensor, faces: torch.Tensor, raster: Raster, kind: str) -> torch.Tensor:
    """(B, H, W, C) un-antialiased image of ``kind`` (differentiable w.r.t. verts)."""
    mode = sk.MODES[kind]
    vn = vertex_normals_numba(verts, faces) if mode in (sk.MODE_SHADED, sk.MODE_NORMAL) else None
    return _Shade.apply(verts, vn, faces, raster.mvp, raster.tri_id, mode)


def antialias_numba(color: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor,
                    raster: Raster) -> torch.Tensor:
    """Analytic antialiasing of ``color`` (B, H, W, C), differentiable w.r.t. color and verts."""
    return _Antialias.apply(color.to(verts.dtype), verts, faces, raster, None)


def render_numba(verts: torch.Tensor, faces: torch.Tensor, raster: Raster, kind: str,
                 antialias: bool) -> torch.Tensor:
    img = shade_numba(verts, faces, raster, kind)
    return antialias_numba(img, verts, faces, raster) if antialias else img


def loss_numba(verts: torch.Tensor, faces: torch.Tensor, raster: Raster, target: torch.Tensor,
               antialias: bool, kind: str = "shaded") -> torch.Tensor:
    img = shade_numba(verts, faces, raster, kind)
    if antialias:
        return _Antialias.apply(img, verts, faces, raster, target)
    return _L1.apply(img, target)
