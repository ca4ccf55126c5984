"""What Bake Maps (and ``batch.py --maps``) computes before any Blender data is made: the
atlas (the base object's own UV map where it fits, else a new xatlas one), the height map
fitted to the source on it, the normal map of the surface it draws and the source's
textures carried onto it (the worker's part)."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..core.maps import Atlas, AtlasError, Carry, Maps, atlas_from_uvs, carry
from ..core.maps.make import LEVEL, make_maps
from ..core.mesh.trimesh import TriMesh
from ..core.micro.micromesh import MicroMesh
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


class Baked(NamedTuple):
    maps: Maps
    carried: list                      # one per ``textures.images`` (empty without textures)
    base_normal: np.ndarray | None     # the source's normal map about the base, when asked


def bake_with_textures(mm: MicroMesh, reference: TriMesh | None, resolution: int, textures,
                       progress, should_stop, atlas: Atlas | None = None,
                       base_normal: bool = False, level: int = LEVEL) -> Baked:
    """The worker's part of Bake Maps: on ``atlas`` (default: a new one) the maps of
    ``core.maps.make_maps`` (the height map fitted to ``reference``, world space, None: to
    the micro-mesh itself where the source is gone), and the source's textures carried onto
    it, all in one pass over the texels (``core.maps.carry``). A normal map is carried into the
    atlas' tangent frame about the surface (the maps object renders it on the displaced
    surface); with ``base_normal``, also about the base (for an engine's undisplaced base:
    ``result_files.engine_normal_map``)."""
    maps = make_maps(mm, reference, resolution, atlas, level, progress, should_stop)
    if textures is None:
        return Baked(maps, [], None)
    progress({"phase": "texture", "iteration": 0, "total": 1})
    items = [Carry(t.pixels, normal=t.socket == source_texture.NORMAL) for t in textures.images]
    normal = next((t for t in textures.images if t.socket == source_texture.NORMAL), None)
    if base_normal and normal is not None:
        items.append(Carry(normal.pixels, normal=True, about_base=True))
    out = carry(mm, maps, textures.mesh, textures.uv, items)
    n = len(textures.images)
    return Baked(maps, out[:n], out[n] if len(out) > n else None)
