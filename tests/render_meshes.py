"""Small meshes and helpers for the renderer tests (no files needed)."""
from __future__ import annotations

import numpy as np
import torch


def icosphere(subdivisions: int = 2, noise: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere (optionally with radial noise): vertices (n, 3) float64, faces (m, 3) int64."""
    t = (1 + 5 ** 0.5) / 2
    v = [np.array(p, float) for p in [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t],
                                      [0, 1, t], [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1],
                                      [-t, 0, -1], [-t, 0, 1]]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
         [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(subdivisions):
        mids: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int) -> int:
            k = (min(a, b), max(a, b))
            if k not in mids:
                mids[k] = len(v)
                v.append((v[a] + v[b]) / 2)
            return mids[k]

        nf = []
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    vv = np.array(v)
    vv /= np.linalg.norm(vv, axis=1, keepdims=True)
    if noise:
        vv *= 1 + noise * np.random.default_rng(seed).standard_normal((len(vv), 1))
    return vv, np.array(f, dtype=np.int64)


def tensors(v: np.ndarray, f: np.ndarray, dtype=torch.float32) -> tuple[torch.Tensor, torch.Tensor]:
    return torch.tensor(v, dtype=dtype), torch.tensor(f, dtype=torch.int64)
