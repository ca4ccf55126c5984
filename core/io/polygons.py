"""What the mesh readers share: their error type and the fan triangulation of polygons."""
from __future__ import annotations

import numpy as np


class MeshFileError(ValueError):
    """The file is not a mesh this reader understands (bad, truncated or unsupported)."""


def fan(polys: list[np.ndarray] | np.ndarray, counts: np.ndarray | None = None) -> np.ndarray:
    """Triangulate polygons (rows of equal length, or a ragged list) as fans."""
    if isinstance(polys, np.ndarray):
        k = polys.shape[1]
        if k < 3:
            raise MeshFileError("face with fewer than 3 vertices")
        tris = [np.stack([polys[:, 0], polys[:, i], polys[:, i + 1]], axis=1) for i in range(1, k - 1)]
        return np.stack(tris, axis=1).reshape(-1, 3)
    out = []
    for p in polys:
        if len(p) < 3:
            raise MeshFileError("face with fewer than 3 vertices")
        out.append(np.stack([np.full(len(p) - 2, p[0]), p[1:-1], p[2:]], axis=1))
    return np.concatenate(out) if out else np.zeros((0, 3), np.int64)
