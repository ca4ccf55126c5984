"""Bundles and input checks shared by every renderer op.

Conventions (see ``core.render.cameras``): OpenGL clip space, image row 0 at the top, one sample at
each pixel centre (column c, row r) = screen (c + 0.5, r + 0.5). Screen x = (x/w + 1) W / 2,
screen y = (1 - y/w) H / 2 where (x, y, z, w) = mvp @ (v, 1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .topology import index_range


class RenderError(ValueError):
    """The renderer cannot use its input (bad shapes, indices, cameras or backend)."""


BACKENDS = ("auto", "numba", "torch")


@dataclass(frozen=True)
class Raster:
    """Visibility of one mesh from a batch of B cameras.

    tri_id: (B, H, W) int32, index into ``faces``, -1 = background.
    depth:  (B, H, W) float32 view-space depth of the visible surface (clip w, i.e. distance
            along the camera's viewing axis), +inf on the background.
    mvp:    (B, 4, 4) float64 world -> clip matrices the raster was made with (on the same
            device as ``tri_id``).
    n_faces: number of faces rasterised (guards reuse with another mesh).
    edge_flags: (B, H, W) uint8 or None; bit e set where edge e of the pixel's face is a
            silhouette in that view (made by the numba rasteriser; the antialiasing uses it to
            skip interior pixel pairs, and computes it where absent).
    """

    tri_id: torch.Tensor
    depth: torch.Tensor
    mvp: torch.Tensor
    width: int
    height: int
    n_faces: int
    edge_flags: torch.Tensor | None = None

    @property
    def mask(self) -> torch.Tensor:
        """(B, H, W) bool, covered pixels."""
        return self.tri_id >= 0


def check_backend(backend: str, device: torch.device) -> str:
    """Resolve ``backend`` ("auto" -> numba on CPU tensors, torch elsewhere)."""
    if backend not in BACKENDS:
        raise RenderError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "auto":
        return "numba" if device.type == "cpu" else "torch"
    if backend == "numba" and device.type != "cpu":
        raise RenderError("the numba backend runs on CPU tensors only; use backend='torch'")
    return backend


def check_mesh(verts: torch.Tensor, faces: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Validate (N, 3) float vertices and (M, 3) integer faces on one device."""
    if not isinstance(verts, torch.Tensor) or not isinstance(faces, torch.Tensor):
        raise RenderError("verts and faces must be torch tensors")
    if verts.ndim != 2 or verts.shape[1] != 3 or not verts.is_floating_point():
        raise RenderError(f"verts must be a float (N, 3) tensor, got {tuple(verts.shape)} {verts.dtype}")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.is_floating_point():
        raise RenderError(f"faces must be an integer (M, 3) tensor, got {tuple(faces.shape)} {faces.dtype}")
    if faces.device != verts.device:
        raise RenderError("verts and faces must be on the same device")
    if len(faces):
        # on a GPU, cached per faces tensor: reading the range back waits for the GPU
        lo, hi = index_range(faces) if faces.is_cuda else (int(faces.min()), int(faces.max()))
        if lo < 0 or hi >= len(verts):
            raise RenderError("face index out of range")
    return verts, faces


def camera_mvp(cams, device: torch.device) -> torch.Tensor:
    """(B, 4, 4) float64 world -> clip matrices of a ``core.render.cameras.Cameras`` on ``device``."""
    if not hasattr(cams, "mvp") or not hasattr(cams, "width"):
        raise RenderError("cams must be a core.render.cameras.Cameras")
    mvp = np.ascontiguousarray(cams.mvp, dtype=np.float64)
    if not np.isfinite(mvp).all():
        raise RenderError("camera matrices contain NaN or infinity")
    return torch.from_numpy(mvp).to(device)


def check_raster(raster: Raster, faces: torch.Tensor, cams) -> Raster:
    """A precomputed raster must belong to these faces and cameras."""
    if not isinstance(raster, Raster):
        raise RenderError("raster must be a core.render.Raster from rasterize()")
    if raster.n_faces != len(faces):
        raise RenderError("raster was made for another mesh (face count differs)")
    if (raster.width, raster.height) != (cams.width, cams.height) or len(raster.tri_id) != len(cams):
        raise RenderError("raster was made for other cameras (count or image size differs)")
    return raster
