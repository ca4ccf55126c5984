"""A texture of the source on the base's atlas, so the baked asset keeps its look: the texels'
source points and the plain images' sampling (``carry`` runs them).

Each atlas texel stands for a point of the micro-surface (the base point of its face and
barycentrics, moved by the height map along the interpolated direction); the nearest point of
the source surface gives the source triangle and barycentrics, its UVs the place where the
source image is sampled (bilinear, as a renderer samples it). Texels outside the charts are
bled from their neighbours like the other maps.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..spatial.bake import nearest_points
from ..spatial.barycentric import barycentrics
from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from .atlas import dilate, texel_faces
from .bake import Maps, base_point, sample, unit_directions


class TransferError(ValueError):
    """Inputs a texture cannot be carried over with."""


class TextureSink:
    """One image of the source, sampled at each texel's source UV (bilinear)."""

    def __init__(self, image, res: int) -> None:
        self.image = checked_image(image)
        self.out = np.zeros((res, res, self.image.shape[2]))

    def add(self, p: "SourcePoints", at: np.ndarray) -> None:
        self.out[p.y, p.x] = sample(self.image, at)

    def done(self, maps: Maps, padding: int) -> np.ndarray:
        return dilate(self.out, maps.filled, padding).astype(np.float32)


@dataclass(eq=False)
class SourcePoints:
    """Filled texels ``y``, ``x`` (q,) of an atlas, the texel's base face ``texel_face``,
    barycentrics ``texel_bary`` and unit ``direction`` (q, 3) (the base's, interpolated), and
    the nearest source ``face`` (q,) and its ``bary`` (q, 3) to the point of the micro-surface
    the texel stands for."""
    y: np.ndarray
    x: np.ndarray
    texel_face: np.ndarray
    texel_bary: np.ndarray
    direction: np.ndarray
    face: np.ndarray
    bary: np.ndarray


def source_points(mm: MicroMesh, maps: Maps, source: TriMesh, chunk: int = 1 << 20):
    """:class:`SourcePoints` of ``maps``' filled texels, ``chunk`` texels at a time."""
    res = maps.height.shape[0]
    face, bary = texel_faces(maps.atlas, res, res)
    ys, xs = np.nonzero(face >= 0)
    U = unit_directions(mm)
    for s in range(0, len(ys), chunk):
        y, x = ys[s:s + chunk], xs[s:s + chunk]
        P, n = base_point(mm.base, U, face[y, x], bary[y, x])
        near, sf, _ = nearest_points(P + n * maps.height[y, x, None], source)
        corners = source.vertices[source.faces[sf]]
        yield SourcePoints(y, x, face[y, x], bary[y, x], n, sf, barycentrics(near, corners))


def checked_uv(source: TriMesh, source_uv: np.ndarray) -> np.ndarray:
    uv = np.asarray(source_uv, dtype=np.float64)
    if uv.shape != (source.n_faces, 3, 2) or not np.isfinite(uv).all():
        raise TransferError(f"source UVs must be finite, one (3, 2) block per face "
                            f"({source.n_faces}), got {uv.shape}")
    return uv


def checked_image(image) -> np.ndarray:
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 2:
        img = img[..., None]
    if img.ndim != 3 or min(img.shape[:2]) < 2:
        raise TransferError(f"the source image must be (H, W[, C]) with H, W >= 2, got "
                            f"{img.shape}")
    return img
