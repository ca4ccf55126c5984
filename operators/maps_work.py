"""What Bake Maps (and ``batch.py --maps``) computes before any Blender data is made: the
atlas (the base object's own UV map where it fits, else a new xatlas one), the height and
normal maps on it and the source's textures carried onto it (the worker's part)."""
from __future__ import annotations

import numpy as np

from ..core.maps import (Atlas, AtlasError, atlas_from_uvs, bake_maps, transfer_normal_map,
                         transfer_textures)
from ..core.micromesh import MicroMesh
from . import bl_mesh, source_texture


def own_atlas(base_obj, mm: MicroMesh, resolution: int) -> tuple[Atlas | None, str]:
    """(the base object's own UV map as the atlas, "") where it has one that fits the
    micro-mesh's base (the same triangles; ``core.maps.atlas_from_uvs``'s checks): an artist's
    layout and seams, or UVs the base inherited, are kept. Else (None, why not; "" where the
    base has no UV map)."""
    if base_obj is None or base_obj.type != "MESH" or base_obj.data.uv_layers.active is None:
        return None, ""
    _, faces = bl_mesh.mesh_arrays(base_obj.data)
    if faces.shape != mm.base.faces.shape or not np.array_equal(faces, mm.base.faces):
        return None, (f"'{base_obj.name}' has changed since the construction: its UV map is "
                      "not used, a new atlas is made")
    try:
        return atlas_from_uvs(mm.base, bl_mesh.corner_uvs(base_obj.data), resolution), ""
    except AtlasError as e:
        return None, f"'{base_obj.name}''s UV map is not used ({e}): a new atlas is made"


def bake_with_textures(mm: MicroMesh, resolution: int, textures, progress, should_stop,
                       atlas: Atlas | None = None):
    """(maps, the source's textures on their atlas: one per ``textures.images``, or an empty
    list): the worker's part of Bake Maps, on ``atlas`` (default: a new one). A normal map is
    carried into the atlas' tangent frame about the surface (the maps object renders it on
    the displaced surface)."""
    maps = bake_maps(mm, resolution, atlas=atlas, progress=progress, should_stop=should_stop)
    if textures is None:
        return maps, []
    progress({"phase": "texture", "iteration": 0, "total": 1})
    plain = [t.pixels for t in textures.images if t.socket != source_texture.NORMAL]
    carried = iter(transfer_textures(mm, maps, textures.mesh, textures.uv, plain) if plain else [])
    out = []
    for t in textures.images:
        if t.socket == source_texture.NORMAL:
            out.append(transfer_normal_map(mm, maps, textures.mesh, textures.uv, t.pixels))
        else:
            out.append(next(carried))
    return maps, out
