"""The base vertices a construction holds where the base builder put them: those whose whole
star already lies on the reference (a CAD part's flat faces, a modelled asset's low-poly
parts). Moving them cannot bring the surface closer there; it only makes the values around
them vary, and the shell with them."""
from __future__ import annotations

import numpy as np

from ..closest import closest_point_index
from ..mesh import TriMesh

# Points of each base face tested against the reference: the corners, the edge midpoints, the
# centroid and three points between it and the corners (barycentric weights).
_SAMPLES = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, .5, 0], [.5, 0, .5], [0, .5, .5],
                     [1 / 3, 1 / 3, 1 / 3], [.6, .2, .2], [.2, .6, .2], [.2, .2, .6]])


def vertices_on_reference(base: TriMesh, reference: TriMesh, tolerance: float = 1e-6
                          ) -> np.ndarray:
    """(nv,) bool: True where every face around the base vertex lies on ``reference``: all of
    its sample points within ``tolerance`` × the reference's bounding-box diagonal of it."""
    points = np.einsum("sk,fkc->fsc", _SAMPLES, base.vertices[base.faces]).reshape(-1, 3)
    limit = tolerance * reference.bbox_diagonal
    _, _, dist = closest_point_index(reference).query(points, max_distance=2.0 * limit)
    on = (dist <= limit).reshape(base.n_faces, -1).all(1)
    held = np.ones(base.n_vertices, bool)
    for k in range(3):
        np.logical_and.at(held, base.faces[:, k], on)
    used = np.zeros(base.n_vertices, bool)
    used[base.faces.reshape(-1)] = True
    return held & used
