"""Reference samples for the fit: area-weighted points and normals on the reference, at
least as dense as the micro-triangles they must hold."""
from __future__ import annotations

from functools import cache, cached_property

import numpy as np

from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh

# At most 4**_MAX_LEVEL samples on one reference face.
_MAX_LEVEL = 5
# Samples made, matched and summed at a time: their temporaries (about 200 bytes a sample)
# stay under glibc's 32 MB mapping threshold, so they are reused from the heap rather than
# mapped and zero-filled anew for every chunk.
CHUNK = 1 << 17


class FitError(ValueError):
    """Inputs the fit cannot use."""


@cache
def _subtriangle_centroids(level: int) -> np.ndarray:
    """(4**level, 3) barycentrics of the centroids of a triangle's uniform subdivision."""
    r = 1 << level
    i, j = np.meshgrid(np.arange(r), np.arange(r), indexing="ij")
    up = i + j <= r - 1
    down = i + j <= r - 2
    u = np.concatenate([(i[up] + 1 / 3) / r, (i[down] + 2 / 3) / r])
    v = np.concatenate([(j[up] + 1 / 3) / r, (j[down] + 2 / 3) / r])
    return np.stack([1.0 - u - v, u, v], 1)


class Samples:
    """Area-weighted points and unit normals on a reference's faces, made a run of faces at a
    time (:meth:`chunks`) rather than held: at a few per micro-triangle they are the largest
    arrays of a fit (56 bytes a sample). Only a weight per face is kept.

    Each face gets the centroids of its uniform subdivision at its level (4**level samples);
    the samples are ordered by level, then face, then centroid. Weights are the area each
    sample stands for, over their mean.
    """

    def __init__(self, reference: TriMesh, level: np.ndarray):
        self.reference = reference
        self.level = np.asarray(level, dtype=np.int64)
        areas = reference.face_areas
        w = np.concatenate([np.repeat(areas[f] / 4 ** lv, 4 ** lv) for lv, f in self._groups()])
        self._count, self._mean = len(w), max(w.mean(), 1e-300)
        self._face_weight = areas / 4.0 ** self.level

    def __len__(self) -> int:
        return self._count

    @property
    def weights(self) -> np.ndarray:
        """(s,) every sample's weight, in order (made on each call)."""
        return np.concatenate([self._weights(lv, f) for _, lv, f in self.parts()])

    def _weights(self, level: int, faces: np.ndarray) -> np.ndarray:
        return np.repeat(self._face_weight[faces], 4 ** level) / self._mean

    def _groups(self):
        for lv in np.unique(self.level):
            yield int(lv), np.flatnonzero(self.level == lv)

    def parts(self, size: int = CHUNK):
        """(slice of the samples, level, faces) in order, about ``size`` samples each (whole
        faces of one level): the runs :meth:`chunks` makes, without their points."""
        pos = 0
        for lv, faces in self._groups():
            step = max(1, size // 4 ** lv)
            for lo in range(0, len(faces), step):
                f = faces[lo:lo + step]
                yield slice(pos, pos + len(f) * 4 ** lv), lv, f
                pos += len(f) * 4 ** lv

    @cached_property
    def _normals(self) -> np.ndarray:
        return self.reference.face_normals

    def points(self, level: int, faces: np.ndarray) -> np.ndarray:
        """(c, 3) the samples of ``faces`` (all of ``level``)."""
        w = _subtriangle_centroids(level)
        pts = np.einsum("sk,fkc->fsc", w, self.reference.vertices[self.reference.faces[faces]])
        return pts.reshape(-1, 3)

    def points_at(self, level: int, faces: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """(r, 3) the samples ``rows`` (indices into :meth:`points` of ``faces``) alone: the
        same values, computed for those only."""
        w = _subtriangle_centroids(level)[rows % 4 ** level]
        v = self.reference.vertices[self.reference.faces[faces[rows // 4 ** level]]]
        return np.einsum("sk,skc->sc", w, v)

    def chunks(self, size: int = CHUNK):
        """(slice of the samples, points (c, 3), normals (c, 3), weights (c,)) in order, about
        ``size`` samples each (whole faces of one level)."""
        for part, lv, f in self.parts(size):
            normals = np.repeat(self._normals[f], 4 ** lv, axis=0)
            yield part, self.points(lv, f), normals, self._weights(lv, f)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(points (s, 3), normals (s, 3), weights (s,)) all at once."""
        parts = list(self.chunks())
        return (np.concatenate([p for _, p, _, _ in parts]),
                np.concatenate([n for _, _, n, _ in parts]),
                np.concatenate([w for _, _, _, w in parts]))


def reference_samples(reference: TriMesh, sample_area: float | None = None) -> Samples:
    """:class:`Samples` on the reference's faces, each face at the level that makes a sample
    cover at most ``sample_area`` (4 samples at least, 4**5 at most), so large faces (the flat
    sides of CAD parts) are sampled as densely as the micro-mesh they must hold flat."""
    areas = reference.face_areas
    level = np.ones(len(areas), dtype=np.int64)
    if sample_area is not None:
        if not sample_area > 0:
            raise FitError("the sample area must be positive")
        with np.errstate(divide="ignore"):
            want = np.ceil(np.log(np.maximum(areas / sample_area, 1.0)) / np.log(4.0))
        level = np.clip(want.astype(np.int64), 1, _MAX_LEVEL)
    return Samples(reference, level)


def fit_samples(mm: MicroMesh, reference: TriMesh, density: float = 2.0):
    """:func:`reference_samples` at least ``density`` per micro-triangle of ``mm``."""
    T = mm.topology.triangles
    area = _areas(mm.micro_vertex_positions(), T).sum()
    return reference_samples(reference, area / (len(T) * density))


def _areas(X: np.ndarray, T: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]), axis=1)
