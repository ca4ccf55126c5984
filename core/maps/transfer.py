"""A texture of the source carried onto the base's atlas, so the baked asset keeps its look.

Each atlas texel stands for a point of the micro-surface (the base point of its face and
barycentrics, moved by the height map along the interpolated direction); the nearest point of
the source surface gives the source triangle and barycentrics, its UVs the place where the
source image is sampled (bilinear, as a renderer samples it). Texels outside the charts are
bled from their neighbours like the other maps.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..bake import nearest_points
from ..barycentric import barycentrics
from ..mesh import TriMesh
from ..micromesh import MicroMesh
from .atlas import dilate, texel_faces
from .bake import Maps, base_point, sample, unit_directions


class TransferError(ValueError):
    """Inputs a texture cannot be carried over with."""


def transfer_texture(mm: MicroMesh, maps: Maps, source: TriMesh, source_uv: np.ndarray,
                     image: np.ndarray, padding: int = 4, chunk: int = 1 << 20) -> np.ndarray:
    """The source's ``image`` (H, W, C, row 0 at v = 0) on ``maps``' atlas: (R, R, C) float32
    (:func:`transfer_textures` with one image)."""
    return transfer_textures(mm, maps, source, source_uv, [image], padding, chunk)[0]


def transfer_textures(mm: MicroMesh, maps: Maps, source: TriMesh, source_uv: np.ndarray,
                      images: list, padding: int = 4, chunk: int = 1 << 20) -> list:
    """The source's ``images`` (each (H, W[, C]), row 0 at v = 0, all mapped by the same UVs)
    on ``maps``' atlas: a list of (R, R, C) float32, one per image. The nearest source point
    of each texel is found once for all of them.

    Args:
        mm: the micro-mesh the maps were baked from (the frame of ``source``).
        maps: its height map and atlas (:func:`core.maps.bake_maps`).
        source: the textured surface, usually the construction's reference.
        source_uv: (source.n_faces, 3, 2) the UVs of its triangles' corners.
        images: its textures (base colour, roughness, ...); any number of channels each.
    """
    uv = checked_uv(source, source_uv)
    first = {}                        # the same array given twice is carried once
    slot = [first.setdefault(id(image), len(first)) for image in images]
    imgs = [checked_image(image) for image in {id(i): i for i in images}.values()]
    res = maps.height.shape[0]
    outs = [np.zeros((res, res, img.shape[2])) for img in imgs]
    for p in source_points(mm, maps, source, chunk):
        at = np.einsum("qk,qkc->qc", p.bary, uv[p.face])
        for img, out in zip(imgs, outs):
            out[p.y, p.x] = sample(img, at)
    done = [dilate(out, maps.filled, padding).astype(np.float32) for out in outs]
    return [done[k] for k in slot]


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
        P, n = base_point(mm, U, face[y, x], bary[y, x])
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
