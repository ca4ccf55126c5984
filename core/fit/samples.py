"""Reference samples for the fit: area-weighted points and normals on the reference, at
least as dense as the micro-triangles they must hold."""
from __future__ import annotations

import numpy as np

from ..mesh import TriMesh
from ..micromesh import MicroMesh

# At most 4**_MAX_LEVEL samples on one reference face.
_MAX_LEVEL = 5


class FitError(ValueError):
    """Inputs the fit cannot use."""


def _subtriangle_centroids(level: int) -> np.ndarray:
    """(4**level, 3) barycentrics of the centroids of a triangle's uniform subdivision."""
    r = 1 << level
    i, j = np.meshgrid(np.arange(r), np.arange(r), indexing="ij")
    up = i + j <= r - 1
    down = i + j <= r - 2
    u = np.concatenate([(i[up] + 1 / 3) / r, (i[down] + 2 / 3) / r])
    v = np.concatenate([(j[up] + 1 / 3) / r, (j[down] + 2 / 3) / r])
    return np.stack([1.0 - u - v, u, v], 1)


def reference_samples(reference: TriMesh, sample_area: float | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (s, 3), unit normals (s, 3), weights (s,)) on the reference's faces.

    Each face gets the centroids of its uniform subdivision at the level that makes a sample
    cover at most ``sample_area`` (4 samples at least, 4**5 at most), so large faces (the flat
    sides of CAD parts) are sampled as densely as the micro-mesh they must hold flat. Weights
    are the area each sample stands for, over their mean.
    """
    areas = reference.face_areas
    level = np.ones(len(areas), dtype=np.int64)
    if sample_area is not None:
        if not sample_area > 0:
            raise FitError("the sample area must be positive")
        with np.errstate(divide="ignore"):
            want = np.ceil(np.log(np.maximum(areas / sample_area, 1.0)) / np.log(4.0))
        level = np.clip(want.astype(np.int64), 1, _MAX_LEVEL)
    corners = reference.vertices[reference.faces]
    face_normals = reference.face_normals
    pts, normals, weights = [], [], []
    for lv in np.unique(level):
        faces = np.flatnonzero(level == lv)
        w = _subtriangle_centroids(int(lv))
        pts.append(np.einsum("sk,fkc->fsc", w, corners[faces]).reshape(-1, 3))
        normals.append(np.repeat(face_normals[faces], len(w), axis=0))
        weights.append(np.repeat(areas[faces] / len(w), len(w)))
    weights = np.concatenate(weights)
    return (np.concatenate(pts), np.concatenate(normals),
            weights / max(weights.mean(), 1e-300))


def fit_samples(mm: MicroMesh, reference: TriMesh, density: float = 2.0):
    """:func:`reference_samples` at least ``density`` per micro-triangle of ``mm``."""
    T = mm.topology.triangles
    area = _areas(mm.micro_vertex_positions(), T).sum()
    return reference_samples(reference, area / (len(T) * density))


def _areas(X: np.ndarray, T: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]), axis=1)
