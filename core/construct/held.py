"""The base vertices a construction holds where the base builder put them.

- Those whose whole star already lies on the reference (a CAD part's flat faces, a modelled
  asset's low-poly parts): moving them cannot bring the surface closer there; it only makes
  the values around them vary, and the shell with them. Neither the optimiser nor the fit's
  base round moves them.
- Those that lie on the reference themselves (the base builder's placement lands exactly on
  it where the planes meet: corners, creases, flat parts): the optimiser, whose image
  gradients from a few views at a time are noisy, leaves them there; the fit's base round,
  guarded by the shading error and the shell, may still move them.
"""
from __future__ import annotations

import numpy as np

from ..spatial.closest import closest_point_index
from ..mesh.trimesh import TriMesh

# Points of each base face tested against the reference: the corners, the edge midpoints, the
# centroid and three points between it and the corners (barycentric weights).
_SAMPLES = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, .5, 0], [.5, 0, .5], [0, .5, .5],
                     [1 / 3, 1 / 3, 1 / 3], [.6, .2, .2], [.2, .6, .2], [.2, .2, .6]])


def held_vertices(base: TriMesh, reference: TriMesh, tolerance: float = 1e-6
                  ) -> tuple[np.ndarray, np.ndarray]:
    """((nv,) bool, (nv,) bool): the base vertices every face around which lies on
    ``reference`` (all of its sample points within ``tolerance`` × the reference's
    bounding-box diagonal of it), and those that lie on it themselves (the first are among
    the second)."""
    limit = tolerance * reference.bbox_diagonal
    index = closest_point_index(reference)
    points = np.einsum("sk,fkc->fsc", _SAMPLES, base.vertices[base.faces]).reshape(-1, 3)
    _, _, dist = index.query(points, max_distance=2.0 * limit)
    on = (dist <= limit).reshape(base.n_faces, -1).all(1)
    star = np.zeros(base.n_vertices, bool)
    star[base.faces.reshape(-1)] = True                      # used vertices only
    for k in range(3):
        np.logical_and.at(star, base.faces[:, k], on)
    _, _, dist = index.query(base.vertices, max_distance=2.0 * limit)
    return star, star | (dist <= limit)
