"""Where a fitted micro-mesh still misses the reference, per base face."""
from __future__ import annotations

import numpy as np

from ..closest import ClosestPointIndex
from ..micromesh import MicroMesh


def surface_errors(mm: MicroMesh, samples) -> tuple[np.ndarray, np.ndarray]:
    """(distance, normal) per base face (nf,) of the reference samples (of
    :func:`reference_samples`) whose nearest micro-surface point lies on that face: the
    weighted squared distance, and the weighted squared difference between the sample's normal
    and the micro-triangle's (what shading sees). Where the fitted micro-mesh still misses the
    reference."""
    pts, normals, weights = samples
    tess = mm.tessellate()
    V, T = tess.vertices, tess.triangles
    _, tri, dist = ClosestPointIndex(V, T).query(pts)
    tn = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    tn /= np.maximum(np.linalg.norm(tn, axis=1, keepdims=True), 1e-300)
    face = tess.triangle_face[tri]
    nf = mm.base.n_faces
    return (np.bincount(face, weights=weights * dist ** 2, minlength=nf),
            np.bincount(face, weights=weights * ((tn[tri] - normals) ** 2).sum(1), minlength=nf))
