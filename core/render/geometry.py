"""Small differentiable geometry shared by both backends: vertex normals, clip coordinates.

Everything here is plain torch (runs on any device) and cheap (O(vertices + faces)).
"""
from __future__ import annotations

import torch

from . import fused_normals
from .lighting import NORMAL_EPS
from .scatter import gather, scatter_add


def normalize(v: torch.Tensor) -> torch.Tensor:
    """v / |v| along the last axis; a zero vector stays zero (finite gradient)."""
    return v * torch.rsqrt((v * v).sum(-1, keepdim=True) + NORMAL_EPS)


def vertex_normals(verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """(N, 3) unit area-weighted vertex normals (sum of the incident faces' cross products;
    on CUDA summed by fused kernels where they run)."""
    fused = fused_normals.normal_sums(verts, faces)
    if fused is not None:
        return normalize(fused)
    f = faces.long()
    v0, v1, v2 = (gather(verts, f[:, k]) for k in range(3))
    fn = torch.linalg.cross(v1 - v0, v2 - v0)
    vn = torch.zeros_like(verts)
    for k in range(3):
        vn = scatter_add(vn, f[:, k], fn)
    return normalize(vn)


def screen_coords(verts: torch.Tensor, mvp: torch.Tensor, width: int, height: int
                  ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Exact float64 raster coordinates of (N, 3) verts under one (4, 4) mvp.

    Returns (sx, sy, w, z) each (N,); sx, sy in pixels (centres at +0.5). The arithmetic order is
    the one the numba rasteriser uses, so both backends make identical coverage decisions.
    """
    v = verts.detach().to(torch.float64)
    vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
    m = mvp.to(torch.float64)

    def row(r: int) -> torch.Tensor:
        return ((m[r, 0] * vx + m[r, 1] * vy) + m[r, 2] * vz) + m[r, 3]

    x, y, z, w = row(0), row(1), row(2), row(3)
    sx = (x / w + 1.0) * (0.5 * width)
    sy = (1.0 - y / w) * (0.5 * height)
    return sx, sy, w, z
