"""Edge neighbours of faces, for silhouette tests in the antialiasing (cached per faces tensor).

Edge e of face f is (faces[f, e], faces[f, (e + 1) % 3]); ``face_neighbours(faces)[f, e]`` is the
other face on that edge, or -1 on a boundary or non-manifold edge (treated as a silhouette).
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np
import torch

_CACHE: "OrderedDict[tuple, tuple[torch.Tensor, torch.Tensor]]" = OrderedDict()
_CACHE_SIZE = 4


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
    # i starts a group of exactly two: eq[i+1] and not eq[i] and not eq[i+2]
    i = np.nonzero(eq[1:-1] & ~eq[:-2] & ~np.append(eq[2:-1], False))[0]
    h0, h1 = order[i], order[i + 1]
    nbr[h0] = h1 // 3
    nbr[h1] = h0 // 3
    return nbr.reshape(m, 3)


def face_neighbours(faces: torch.Tensor) -> torch.Tensor:
    """(M, 3) int32 neighbour across each edge (-1: boundary / non-manifold), on faces' device."""
    key = (faces.data_ptr(), tuple(faces.shape), str(faces.device), faces.dtype)
    hit = _CACHE.get(key)
    if hit is not None and torch.equal(hit[0], faces):
        _CACHE.move_to_end(key)
        return hit[1]
    nbr = torch.from_numpy(_neighbours_numpy(faces.detach().cpu().numpy())).to(faces.device)
    _CACHE[key] = (faces.detach().clone(), nbr)
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return nbr
