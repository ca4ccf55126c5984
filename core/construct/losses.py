"""Regularisers of the construction: shell volume L_sv (and its exact range form, ours),
isotropy L_iso, Laplacian smoothing.

Gathers use ``index_select``, never ``x[idx]``: the backward of advanced indexing
(an accumulating ``index_put_``) sums in a different order from run to run on several CPU
threads, which made constructions differ by float32 ulps; ``index_select``'s backward is
deterministic.

All are differentiable torch functions, scale-normalised (ours) by a squared reference
length ``h`` (the initial mean base edge length in the unit-sphere frame), so that the
paper's weights (10 for L_sv, 1 for L_iso) mean the same for every mesh and base resolution.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch


@dataclass(frozen=True)
class VertexGroups:
    """Pairs (base vertex, micro-vertex) for every micro-vertex in the faces around a base
    vertex (deduplicated); ``count`` is the group size per base vertex."""

    group: torch.Tensor   # (P,) long, base vertex of each pair
    member: torch.Tensor  # (P,) long, micro-vertex of each pair
    count: torch.Tensor   # (n_base,) float
    n_groups: int


def vertex_groups(base_faces: np.ndarray, n_base: int, face_vertex_ptr: np.ndarray,
                  face_vertex_idx: np.ndarray, n_micro: int, device="cpu") -> VertexGroups:
    """Groups for L_sv from the base faces and the micro-vertices of each base face (CSR)."""
    ptr = np.asarray(face_vertex_ptr, dtype=np.int64)
    idx = np.asarray(face_vertex_idx, dtype=np.int64)
    per_face = np.diff(ptr)
    face_of = np.repeat(np.arange(len(per_face)), per_face)
    g = np.concatenate([base_faces[face_of, k] for k in range(3)])
    m = np.concatenate([idx, idx, idx])
    key = np.unique(g * np.int64(n_micro) + m)
    g, m = key // n_micro, key % n_micro
    count = np.bincount(g, minlength=n_base).astype(np.float64)
    return VertexGroups(torch.as_tensor(g, device=device), torch.as_tensor(m, device=device),
                        torch.as_tensor(count, device=device), n_base)


def shell_volume_loss(displacement: torch.Tensor, groups: VertexGroups, h: float = 1.0) -> torch.Tensor:
    """L_sv: mean over base vertices of the variance of the displacements of the micro-vertices
    in the base faces around it, divided by ``h**2``.

    A smooth surrogate of the prismoid shell volume (which only exposes min/max).
    """
    d = displacement.reshape(-1)
    cnt = groups.count.to(d.dtype).clamp_min(1.0)
    vals = d.index_select(0, groups.member)
    mean = torch.zeros(groups.n_groups, dtype=d.dtype, device=d.device).index_add_(0, groups.group, vals) / cnt
    dev = (vals - mean.index_select(0, groups.group)) ** 2
    var = torch.zeros_like(mean).index_add_(0, groups.group, dev) / cnt
    used = groups.count > 0
    return var[used].mean() / (h * h)


def shell_range_loss(displacement: torch.Tensor, groups: VertexGroups, h: float = 1.0) -> torch.Tensor:
    """Mean over base vertices of (max - min) of the displacements in the base faces around
    it, divided by ``h``: exactly the per-vertex scale of the tight bounds
    (:func:`core.micro.bounds.tight_bounds`), so its gradient reaches the micro-vertices that set
    the shell (outliers the variance of :func:`shell_volume_loss` barely sees)."""
    d = displacement.reshape(-1)
    vals = d.index_select(0, groups.member)
    empty = torch.zeros(groups.n_groups, dtype=d.dtype, device=d.device)
    hi = empty.scatter_reduce(0, groups.group, vals, "amax", include_self=False)
    lo = empty.scatter_reduce(0, groups.group, vals, "amin", include_self=False)
    used = groups.count > 0
    return (hi - lo)[used].mean() / h


def isotropy_loss(vertices: torch.Tensor, faces: torch.Tensor, h: float = 1.0) -> torch.Tensor:
    """L_iso: mean over faces of the (population) variance of the three edge lengths, divided
    by ``h**2`` (as-equilateral-as-possible)."""
    v = vertices.index_select(0, faces.reshape(-1)).reshape(*faces.shape, -1)
    e = torch.stack([v[:, 1] - v[:, 0], v[:, 2] - v[:, 1], v[:, 0] - v[:, 2]], dim=1)
    lengths = torch.sqrt((e * e).sum(-1) + 1e-20)
    return lengths.var(dim=1, unbiased=False).mean() / (h * h)


def laplacian_smoothing_loss(x: torch.Tensor, laplacian: torch.Tensor, h: float = 1.0) -> torch.Tensor:
    """Mean squared norm of the (uniform) Laplacian of ``x`` over ``h**2``: the smoothing
    term that replaces the reparameterisation in the paper's ablation (Tab. 1b)."""
    lx = torch.sparse.mm(laplacian, x if x.dim() == 2 else x[:, None])
    return (lx * lx).sum(-1).mean() / (h * h)


def scipy_to_torch_sparse(m, dtype=torch.float32, device="cpu") -> torch.Tensor:
    """A scipy sparse matrix as a torch COO tensor (coalesced)."""
    c = m.tocoo()
    idx = torch.as_tensor(np.vstack([c.row, c.col]).astype(np.int64))
    t = torch.sparse_coo_tensor(idx, torch.as_tensor(c.data, dtype=dtype), c.shape,
                                check_invariants=False)
    return t.coalesce().to(device)


def mean_edge_length(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Mean edge length over face edges (each interior edge counted twice)."""
    v = np.asarray(vertices)[np.asarray(faces)]
    e = np.concatenate([v[:, 1] - v[:, 0], v[:, 2] - v[:, 1], v[:, 0] - v[:, 2]])
    return float(np.linalg.norm(e, axis=1).mean())
