"""Per-vertex sums of per-corner values on CUDA, in a fixed order (no atomics): the last step
of the fused kernels' backward passes (``fused_shade``, ``fused_normals``).

A corner is (face, k), row ``3 * face + k`` of a (M * 3, C) array; a vertex's sum adds its
corners' rows in increasing corner order, so the result is the same on every run.
"""
from __future__ import annotations

import torch

from .scatter import scatter_add
from .topology import vertex_corner_segments
from .triton_kernels import BLOCK_SIZE, guarded, tl, triton

MAX_COLUMNS = 8


def segments(keys: torch.Tensor, n: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Rows grouped by key: (order, start (n,), count (n,)) with the rows of key k at
    ``order[start[k]:start[k] + count[k]]``, in increasing row order; rows of negative keys
    are left out."""
    ordered, order = torch.sort(keys, stable=True)
    k = torch.arange(n, dtype=ordered.dtype, device=keys.device)
    start = torch.searchsorted(ordered, k)
    return order, start, torch.searchsorted(ordered, k, right=True) - start


def corner_segments(faces: torch.Tensor, n_verts: int):
    """``segments`` of the faces' corners by vertex (``topology.vertex_corner_segments``,
    cached per faces tensor), for ``n_verts`` vertices."""
    corners, start, count = vertex_corner_segments(faces)
    if len(start) < n_verts:  # vertices after the largest index in faces: no corners
        pad = torch.zeros(n_verts - len(start), dtype=start.dtype, device=start.device)
        start, count = torch.cat([start, pad]), torch.cat([count, pad])
    return corners, start, count


if triton is not None:
    @triton.jit
    def _vertex_sum_kernel(val_ptr, perm_ptr, start_ptr, count_ptr, out_ptr, n_verts,
                           NCOL: tl.constexpr, BLOCK: tl.constexpr):
        v = tl.program_id(0).to(tl.int64) * BLOCK + tl.arange(0, BLOCK)
        live = v < n_verts
        col = tl.arange(0, 8)
        cm = col < NCOL
        start = tl.load(start_ptr + v, mask=live, other=0)
        count = tl.load(count_ptr + v, mask=live, other=0)
        acc = tl.zeros((BLOCK, 8), tl.float64)
        n_max = tl.max(count, axis=0)
        j = 0
        while j < n_max:
            run = j < count
            corner = tl.load(perm_ptr + start + j, mask=run, other=0)
            acc += tl.load(val_ptr + corner[:, None] * NCOL + col[None, :],
                           mask=run[:, None] & cm[None, :], other=0.0).to(tl.float64)
            j += 1
        tl.store(out_ptr + v[:, None] * NCOL + col[None, :], acc, mask=live[:, None] & cm[None, :])


def vertex_sums(faces: torch.Tensor, values: torch.Tensor, n_verts: int) -> torch.Tensor:
    """(N, C) float64: per vertex, the sum of its corners' rows of ``values`` (M * 3, C),
    C <= 8; ``faces`` (M, 3) int64 contiguous. Where the kernel cannot run, the ordered
    scatter-add of ``scatter`` (the same sums, another order)."""
    ncol = values.shape[1]
    if ncol > MAX_COLUMNS:
        raise ValueError(f"at most {MAX_COLUMNS} columns, got {ncol}")
    out = _kernel_sums(faces, values, n_verts) if triton is not None else None
    if out is None:
        zeros = torch.zeros((n_verts, ncol), dtype=torch.float64, device=values.device)
        out = scatter_add(zeros, faces.reshape(-1), values.to(torch.float64))
    return out


@guarded
def _kernel_sums(faces: torch.Tensor, values: torch.Tensor, n_verts: int) -> torch.Tensor:
    ncol = values.shape[1]
    out = torch.empty((n_verts, ncol), dtype=torch.float64, device=values.device)
    if n_verts:
        perm, start, count = corner_segments(faces, n_verts)
        _vertex_sum_kernel[(triton.cdiv(n_verts, BLOCK_SIZE),)](
            values.contiguous(), perm, start, count, out, n_verts, NCOL=ncol, BLOCK=BLOCK_SIZE)
    return out
