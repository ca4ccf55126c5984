"""Mesh connectivity the kernels need, cached per faces tensor (the optimiser reuses one).

* ``face_neighbours(faces)[f, e]``: the other face on edge e = (faces[f, e], faces[f, (e + 1) % 3]),
  -1 on a boundary or non-manifold edge. The antialiasing calls an edge a silhouette when the two
  faces face opposite ways in a view (or one is degenerate / behind the eye), or it has no
  neighbour -- nvdiffrast's rule.
* ``vertex_corners(faces)``: CSR (ptr (N+1,), corners) of each vertex's incident corners
  f * 3 + k, for race-free per-vertex gathers.
"""
from __future__ import annotations

from collections import OrderedDict
from typing import Callable

import numpy as np
import torch

_CACHE: "OrderedDict[tuple, tuple[torch.Tensor, object]]" = OrderedDict()
_CACHE_SIZE = 8


def _cached(faces: torch.Tensor, what: str, make: Callable[[np.ndarray], object]):
    """Cache keyed by storage address, shape, dtype and the tensor's version counter. The entry
    holds a reference to the tensor itself, so its memory cannot be reused by another tensor while
    cached; in-place edits bump the version counter (shared by all views)."""
    key = (what, faces.data_ptr(), tuple(faces.shape), tuple(faces.stride()), str(faces.device),
           faces.dtype, faces._version)
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        return hit[1]
    value = make(faces.detach().cpu().numpy())
    _CACHE[key] = (faces, value)
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return value


def _neighbours_numpy(f: np.ndarray) -> np.ndarray:
    m = len(f)
    nbr = np.full(3 * m, -1, dtype=np.int32)
    if m == 0:
        return nbr.reshape(0, 3)
    a = f.astype(np.int64)
    b = np.roll(a, -1, axis=1)
    n = int(a.max()) + 1
    key = (np.minimum(a, b) * n + np.maximum(a, b)).ravel()
    order = np.argsort(key, kind="stable")
    sk = key[order]
    eq = np.zeros(len(sk) + 1, dtype=bool)
    eq[1:-1] = sk[1:] == sk[:-1]
    # i starts a group of exactly two half-edges: eq[i+1] and not eq[i] and not eq[i+2]
    i = np.nonzero(eq[1:-1] & ~eq[:-2] & ~np.append(eq[2:-1], False))[0]
    h0, h1 = order[i], order[i + 1]
    nbr[h0] = h1 // 3
    nbr[h1] = h0 // 3
    return nbr.reshape(m, 3)


def face_neighbours(faces: torch.Tensor) -> torch.Tensor:
    """(M, 3) int64 face across each edge (-1: boundary / non-manifold), on faces' device."""
    return _cached(faces, "nbr", lambda f: torch.from_numpy(_neighbours_numpy(f).astype(np.int64)
                                                            ).to(faces.device))


def face_neighbours_int32(faces: torch.Tensor) -> np.ndarray:
    """``face_neighbours`` as a contiguous int32 numpy array, cached."""
    return _cached(faces, "nbr32", _neighbours_numpy)


def _corners_numpy(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    flat = f.astype(np.int64).ravel()
    n = int(flat.max()) + 1 if len(flat) else 0
    order = np.argsort(flat, kind="stable")
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(flat, minlength=n), out=ptr[1:])
    return ptr, order.astype(np.int64)


def vertex_corners(faces: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
    """CSR (ptr, corners) numpy arrays: corners of vertex v are corners[ptr[v]:ptr[v + 1]]."""
    return _cached(faces, "corners", _corners_numpy)


def vertex_corner_segments(faces: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``vertex_corners`` as tensors on the faces' device: (corners, start, count), vertex v's
    corners at corners[start[v]:start[v] + count[v]] (for vertices up to the largest index)."""
    def make(f: np.ndarray):
        ptr, corners = _corners_numpy(f)
        return tuple(torch.from_numpy(a).to(faces.device) for a in (corners, ptr[:-1], np.diff(ptr)))

    return _cached(faces, "corners_dev", make)


def index_range(faces: torch.Tensor) -> tuple[int, int]:
    """(smallest, largest) vertex index in non-empty ``faces``, cached."""
    return _cached(faces, "range", lambda f: (int(f.min()), int(f.max())))


def faces_int32(faces: torch.Tensor) -> np.ndarray:
    """Contiguous int32 numpy copy of CPU faces (halves the kernels' index traffic), cached."""
    return _cached(faces, "f32", lambda f: np.ascontiguousarray(f, dtype=np.int32))
