"""The source's images carried onto the base's atlas in one pass: each texel's nearest source
point is found once (``transfer.source_points``) and every image is sampled there
(``transfer.TextureSink``, ``normal_transfer.NormalSink``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from .bake import Maps
from .normal_transfer import NormalSink
from .transfer import TextureSink, checked_uv, source_points


@dataclass(eq=False)
class Carry:
    """One image to carry: a plain texture (H, W[, C], row 0 at v = 0), or with ``normal`` a
    tangent-space normal map, in the atlas' frame about the surface or, ``about_base``, about
    the base (``normal_transfer``)."""
    image: np.ndarray
    normal: bool = False
    about_base: bool = False


def carry(mm: MicroMesh, maps: Maps, source: TriMesh, source_uv: np.ndarray, items: list,
          padding: int = 4, chunk: int = 1 << 20) -> list:
    """The ``items`` (:class:`Carry`) on ``maps``' atlas, in order: (R, R, C) float32 each
    (a normal map: RGB = (n + 1) / 2). A plain image given twice is carried once.

    Args:
        mm: the micro-mesh the maps were baked from (the frame of ``source``).
        maps: its height map and atlas (:func:`core.maps.bake_maps`).
        source: the textured surface, usually the construction's reference.
        source_uv: (source.n_faces, 3, 2) the UVs of its triangles' corners.
    """
    uv = checked_uv(source, source_uv)
    res = maps.height.shape[0]
    sinks, slot = {}, []
    for it in items:
        key = (id(it.image), it.normal, it.about_base)
        if key not in sinks:
            sinks[key] = (NormalSink(mm, maps, source, uv, it.image, it.about_base) if it.normal
                          else TextureSink(it.image, res))
        slot.append(key)
    for p in source_points(mm, maps, source, chunk):
        at = np.einsum("qk,qkc->qc", p.bary, uv[p.face])
        for sink in sinks.values():
            sink.add(p, at)
    done = {key: sink.done(maps, padding) for key, sink in sinks.items()}
    return [done[key] for key in slot]


def transfer_textures(mm: MicroMesh, maps: Maps, source: TriMesh, source_uv: np.ndarray,
                      images: list, padding: int = 4, chunk: int = 1 << 20) -> list:
    """The source's ``images`` (each (H, W[, C]), row 0 at v = 0, all mapped by the same UVs)
    on ``maps``' atlas: a list of (R, R, C) float32, one per image (:func:`carry`)."""
    return carry(mm, maps, source, source_uv, [Carry(i) for i in images], padding, chunk)


def transfer_texture(mm: MicroMesh, maps: Maps, source: TriMesh, source_uv: np.ndarray,
                     image: np.ndarray, padding: int = 4, chunk: int = 1 << 20) -> np.ndarray:
    """The source's ``image`` on ``maps``' atlas: (R, R, C) float32."""
    return transfer_textures(mm, maps, source, source_uv, [image], padding, chunk)[0]


def transfer_normal_map(mm: MicroMesh, maps: Maps, source: TriMesh, source_uv: np.ndarray,
                        image: np.ndarray, about_base: bool = False, padding: int = 4,
                        chunk: int = 1 << 20) -> np.ndarray:
    """The source's tangent-space normal map ``image`` (H, W, >=3, row 0 at v = 0, RGB in
    [0, 1]) on ``maps``' atlas: (R, R, 3) float32, RGB = (n + 1) / 2 in the atlas' tangent
    frame. ``source_uv``: (source.n_faces, 3, 2) the UVs the map is laid out in."""
    return carry(mm, maps, source, source_uv, [Carry(image, True, about_base)], padding,
                 chunk)[0]
