"""The numba path's geometry on CPU tensors: the rasteriser, the silhouette-edge bits of a
raster that lacks them, and vertex normals with an analytic backward (an autograd Function),
around the kernels of ``raster``, ``edge_flags`` and ``normals``.

The kernel modules themselves import no torch, so a process that only compiles them
(``core.runtime.precompile``) starts without it.
"""
from __future__ import annotations

import numpy as np
import torch

from ..runtime.threads import parallel_for
from .edge_flags import project_and_flag
from .normals import _face_normals, _verts_backward, _vertex_backward, _vertex_forward
from .projection import scratch
from .raster import CHUNK, _raster_kernel
from .topology import face_neighbours_int32, faces_int32, vertex_corners


def _survivor_scratch(n_faces: int, slots: int) -> np.ndarray:
    return np.empty((slots, min(n_faces, CHUNK)), dtype=np.int32)


def rasterize_numba(verts: torch.Tensor, faces: torch.Tensor, mvp: torch.Tensor, width: int,
                    height: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(tri_id int32 (B, H, W), depth float32 (B, H, W) +inf background, silhouette-edge
    bits uint8 (B, H, W) of each pixel's face) on CPU tensors."""
    v = verts.detach().contiguous().numpy()
    f = faces_int32(faces)
    m = mvp.contiguous().numpy()
    nb = len(m)
    tri = np.full((nb, height, width), -1, dtype=np.int32)
    depth = np.full((nb, height, width), np.inf, dtype=np.float32)
    flags = np.zeros((nb, height, width), dtype=np.uint8)
    if len(f) and nb:
        sc, fc = scratch(len(v), len(f), nb)
        parallel_for(_raster_kernel, len(sc), v, f, face_neighbours_int32(faces), m, int(width),
                     int(height), sc, fc, _survivor_scratch(len(f), len(sc)), tri, depth, flags,
                     parts=len(sc))
    return torch.from_numpy(tri), torch.from_numpy(depth), torch.from_numpy(flags)


def edge_flags_numba(verts: torch.Tensor, faces: torch.Tensor, mvp: torch.Tensor,
                     tri: torch.Tensor) -> np.ndarray:
    """Silhouette-edge bits (B, H, W) uint8 for a raster that lacks them."""
    v = verts.detach().contiguous().numpy()
    t = tri.contiguous().numpy()
    flags = np.zeros(t.shape, dtype=np.uint8)
    if len(faces) and len(t):
        sc, fc = scratch(len(v), len(faces), len(t))
        parallel_for(project_and_flag, len(sc), v, faces_int32(faces),
                     face_neighbours_int32(faces), mvp.contiguous().numpy(), t.shape[2],
                     t.shape[1], sc, fc, t, flags, parts=len(sc))
    return flags


def _csr(faces: torch.Tensor, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertex -> corners CSR padded to n vertices (unreferenced trailing vertices: no corners)."""
    ptr, corners = vertex_corners(faces)
    if len(ptr) < n + 1:
        ptr = np.concatenate([ptr, np.full(n + 1 - len(ptr), ptr[-1] if len(ptr) else 0, np.int64)])
    return ptr, corners


class VertexNormals(torch.autograd.Function):
    """(N, 3) unit vertex normals of CPU verts (N, 3) and faces (M, 3)."""

    @staticmethod
    def forward(ctx, verts, faces):
        v = verts.detach().contiguous().numpy()
        f = faces.contiguous().numpy()
        ptr, corners = _csr(faces, len(v))
        fn = np.empty((len(f), 3), v.dtype)
        parallel_for(_face_normals, len(f), v, f, fn)
        vn = np.zeros((len(v), 3), v.dtype)
        inv = np.zeros(len(v), np.float64)
        parallel_for(_vertex_forward, len(v), fn, ptr, corners, vn, inv)
        ctx.save_for_backward(verts)
        ctx.stuff = (faces, vn, inv)
        return torch.from_numpy(vn)

    @staticmethod
    def backward(ctx, gvn):
        (verts,) = ctx.saved_tensors
        faces, vn, inv = ctx.stuff
        v = verts.detach().contiguous().numpy()
        f = faces.contiguous().numpy()
        graw = np.empty_like(vn)
        parallel_for(_vertex_backward, len(vn), gvn.to(verts.dtype).contiguous().numpy(), vn,
                     inv, graw)
        ptr, corners = _csr(faces, len(v))
        gverts = np.zeros_like(v)
        parallel_for(_verts_backward, len(v), v, f, graw, ptr, corners, gverts)
        return torch.from_numpy(gverts), None


def vertex_normals_numba(verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    return VertexNormals.apply(verts, faces)
