"""Plain-torch implementation of every renderer op: the reference for tests and benchmarks,
and the backend for CUDA tensors.

Visibility is ``torch_raster``'s z-buffer. Everything after it is differentiable torch code,
vectorised over views and pixels; autograd does the backward. On CUDA the shading runs as
fused kernels with their own backward (``fused_shade``); the antialiasing is
``torch_antialias``.
"""
from __future__ import annotations

import torch

from .geometry import normalize
from . import fused_shade
from .scatter import gather
from .sh import shade_normals
from .torch_raster import fused_default


def pixel_ndc(index: torch.Tensor, width: int, height: int, dtype) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(view, ndc x, ndc y) of flat pixel indices into (B, H, W)."""
    b = index // (width * height)
    rem = index % (width * height)
    r, c = rem // width, rem % width
    x = (c.to(dtype) + 0.5) * (2.0 / width) - 1.0
    y = 1.0 - (r.to(dtype) + 0.5) * (2.0 / height)
    return b, x, y


def clip_xyw(verts: torch.Tensor, mvp: torch.Tensor, b: torch.Tensor, fv: torch.Tensor
             ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Clip x, y, w (P, 3) of the vertices ``fv`` (P, 3) in views ``b`` (P,) (elementwise:
    no per-pixel 4x4 matrices); differentiable w.r.t. verts, in mvp's dtype."""
    v = gather(verts, fv)  # (P, 3, 3)
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]

    def row(r: int) -> torch.Tensor:
        m = mvp[:, r][b]  # (P, 4)
        return ((m[:, 0:1] * vx + m[:, 1:2] * vy) + m[:, 2:3] * vz) + m[:, 3:4]

    return row(0), row(1), row(3)


def barycentrics_torch(verts: torch.Tensor, faces: torch.Tensor, mvp: torch.Tensor,
                       tri_id: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Perspective-correct barycentrics of the covered pixels, differentiable w.r.t. verts.

    They are the barycentrics of the pixel ray's hit with the visible face's plane: with clip
    coordinates (x_i, y_i, w_i) and pixel NDC (x, y), u_i = x_i - x w_i, t_i = y_i - y w_i and
    b_i is proportional to u_j t_k - u_k t_j. Returns (flat pixel index (P,), face (P,),
    bary (P, 3), clip w of the three vertices (P, 3)).
    """
    nb, height, width = tri_id.shape
    flat = tri_id.reshape(-1)
    index = torch.nonzero(flat >= 0).squeeze(1)
    face = flat[index].long()
    b, x, y = pixel_ndc(index, width, height, verts.dtype)
    cx, cy, cw = clip_xyw(verts, mvp.to(verts.dtype), b, faces.long()[face])
    u = cx - x[:, None] * cw
    t = cy - y[:, None] * cw
    beta = torch.stack([u[:, 1] * t[:, 2] - u[:, 2] * t[:, 1],
                        u[:, 2] * t[:, 0] - u[:, 0] * t[:, 2],
                        u[:, 0] * t[:, 1] - u[:, 1] * t[:, 0]], 1)
    s = beta.sum(1, keepdim=True)
    tiny = torch.finfo(verts.dtype).tiny
    s = torch.where(s.abs() < tiny, torch.full_like(s, tiny), s)
    return index, face, beta * (1.0 / s), cw


def shade_torch(verts: torch.Tensor, faces: torch.Tensor, vnormals: torch.Tensor,
                mvp: torch.Tensor, tri_id: torch.Tensor, kind: str, fused: bool | None = None
                ) -> torch.Tensor:
    """(B, H, W, C) image of ``kind`` ('shaded', 'flat', 'normal', 'depth', 'mask'), background 0.
    ``fused``: 'shaded' and 'flat' as fused kernels (``fused_shade``; default ``fused_default``)."""
    if fused_default(verts.device) if fused is None else fused:
        img = fused_shade.shade(verts, faces, vnormals, mvp, tri_id, kind, plain=_plain_shade)
        if img is not None:
            return img
    nb, height, width = tri_id.shape
    index, face, bary, w = barycentrics_torch(verts, faces, mvp, tri_id)
    if kind == "mask":
        val = torch.ones((len(index), 1), dtype=verts.dtype, device=verts.device)
    elif kind == "depth":
        val = (bary * w).sum(1, keepdim=True)
    elif kind == "flat":
        f = faces.long()[face]
        v0, v1, v2 = (gather(verts, f[:, k]) for k in range(3))
        val = shade_normals(normalize(torch.linalg.cross(v1 - v0, v2 - v0)))
    else:
        n = normalize((bary[:, :, None] * gather(vnormals, faces.long()[face])).sum(1))
        val = shade_normals(n) if kind == "shaded" else n
    out = torch.zeros((nb * height * width, val.shape[1]), dtype=verts.dtype, device=verts.device)
    out = out.index_put((index,), val)
    return out.view(nb, height, width, -1)


def _plain_shade(verts, faces, vnormals, mvp, tri_id, kind):
    return shade_torch(verts, faces, vnormals, mvp, tri_id, kind, fused=False)
