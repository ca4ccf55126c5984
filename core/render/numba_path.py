"""CPU backend: numba rasteriser + fused numba per-pixel kernels with analytic backwards."""
from __future__ import annotations

import torch

from . import torch_path
from .geometry import vertex_normals
from .raster import rasterize_numba
from .topology import face_neighbours
from .types import Raster

__all__ = ["rasterize_numba", "render_numba", "loss_numba"]


def render_numba(verts: torch.Tensor, faces: torch.Tensor, raster: Raster, kind: str,
                 antialias: bool) -> torch.Tensor:
    vn = vertex_normals(verts, faces) if kind in ("shaded", "normal") else None
    img = torch_path.shade_torch(verts, faces, vn, raster.mvp, raster.tri_id, kind)
    if antialias:
        img = torch_path.antialias_torch(img, verts, faces, face_neighbours(faces), raster.mvp,
                                         raster.tri_id, raster.depth)
    return img


def loss_numba(verts, faces, raster, target, antialias):
    img = render_numba(verts, faces, raster, "shaded", antialias)
    return (img - target.to(img.dtype)).abs().mean()
