"""Where a fitted micro-mesh still misses the reference, per base face."""
from __future__ import annotations

import numpy as np

from ..spatial.closest import index_on
from ..micro.micromesh import MicroMesh
from .samples import CHUNK, Samples


def surface_errors(mm: MicroMesh, samples: Samples, chunk: int = CHUNK
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(distance, normal) per base face (nf,) of the reference samples (of
    :class:`.samples.Samples`) whose nearest micro-surface point lies on that face: the
    weighted squared distance, and the weighted squared difference between the sample's normal
    and the micro-triangle's (what shading sees). Where the fitted micro-mesh still misses the
    reference. The samples are matched ``chunk`` at a time."""
    t = mm.topology
    V, T = mm.micro_vertex_positions(), t.triangles
    index = index_on(V, T, t)
    tn = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    tn /= np.maximum(np.linalg.norm(tn, axis=1, keepdims=True), 1e-300)
    nf = mm.base.n_faces
    distance, normal = np.zeros(nf), np.zeros(nf)
    for _, pts, normals, w in samples.chunks(chunk):
        _, tri, dist = index.query(pts)
        face = t.triangle_face[tri]
        distance += np.bincount(face, weights=w * dist ** 2, minlength=nf)
        normal += np.bincount(face, weights=w * ((tn[tri] - normals) ** 2).sum(1), minlength=nf)
    return distance, normal
