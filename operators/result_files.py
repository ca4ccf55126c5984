"""A result's files beside its ``.blend`` (``batch.py``): the formats of
``core.io.formats`` the options chose (the micro-mesh as glTF + ``.bary``, the maps for
renderers), the run report, each written into the result's output set
(``core.io.output_set``) under its temporary name; and the maps made in the scene first."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..core.io import formats
from . import bl_mesh, maps_work, source_texture
from .maps_object import maps_object
from .sources import export_y_up


@dataclass
class SceneMaps:
    """The maps made for a result: what the files are written from, and what the metrics
    record of them."""

    baked: maps_work.Baked
    textures: dict          # the carried textures by glTF slot (``gltf_textures``)
    record: dict


def product(outcome, source, values: str = "r11", layout: str = "bird",
            maps: SceneMaps | None = None) -> formats.Product:
    """What the formats write of ``outcome`` (and its ``maps``), in the input file's
    coordinates (what Blender's importers turned Z-up goes back to Y-up)."""
    p = formats.Product(outcome.micromesh, outcome.bounds, y_up=export_y_up(source),
                        values=values, layout=layout)
    if maps is not None:
        p.maps = maps.baked.maps
        p.normal_map = engine_normal_map(maps.baked)
        p.textures = maps.textures
    return p


def gltf_textures(textures, carried: list) -> dict:
    """The carried textures as glTF's material wants them: {"baseColorTexture": (R, R, 4),
    "metallicRoughnessTexture": (R, R, 3) (roughness in green, metallic in blue; the other
    one's constant where only one is textured), "emissiveTexture": (R, R, 3), the colour times
    the source's Emission Strength (at most 1: glTF's core emission; none where it is 0)},
    where the source has them."""
    by = {t.socket: (t, c) for t, c in zip(textures.images, carried)}
    out = {}
    if "Base Color" in by:
        out["baseColorTexture"] = by["Base Color"][1]
    if "Metallic" in by or "Roughness" in by:
        shape = next(c for t, c in by.values() if t.socket in ("Metallic", "Roughness")).shape
        mr = np.ones(shape[:2] + (3,), np.float32)
        for channel, socket in ((1, "Roughness"), (2, "Metallic")):
            t, c = by.get(socket, (None, None))
            mr[..., channel] = t.values(c) if t else textures.constants[socket]
        out["metallicRoughnessTexture"] = mr
    strength = min(textures.constants.get("Emission Strength", 0.0), 1.0)
    if "Emission Color" in by and strength > 0:
        out["emissiveTexture"] = by["Emission Color"][1][..., :3] * strength
    return out


def engine_normal_map(baked: maps_work.Baked) -> np.ndarray:
    """The glTF base's normal map: the micro-surface's relief (``maps.normal``) or, where the
    source has a tangent-space normal map, the source's shading normals in the base's tangent
    frame, which hold that relief and the source's map together (``baked.base_normal``)."""
    return baked.maps.normal if baked.base_normal is None else baked.base_normal


def scene_maps(context, outcome, source, resolution: int, progress,
               base_obj=None, reference=None) -> SceneMaps:
    """The base with a height map fitted to ``source`` and a normal map: ``<source>_maps`` in
    the scene (images packed), the source's textures carried onto the atlas where its
    material has them (base colour, metallic and roughness, emission); what the formats
    write for renderers (``core.io.formats``, group ``maps``). On ``base_obj``'s own UV map
    where it has one that fits (``maps_work.own_atlas``), else a new atlas. The record: the
    fit's notes (the seam gaps among them, over the diagonal)."""
    mm = outcome.micromesh
    t = time.perf_counter()
    textures = source_texture.read(source)
    atlas, note = maps_work.own_atlas(base_obj, mm, resolution)
    if reference is None:                # the source's arrays, as the construction took them
        reference = bl_mesh.mesh_to_arrays(source)
    baked = maps_work.bake_with_textures(mm, reference, resolution,
                                         textures, progress, lambda: False, atlas=atlas,
                                         base_normal=True)
    obj = maps_object(context, source, mm, baked.maps, f"{source.name}_maps")
    slots = {}
    if baked.carried:
        source_texture.carry_textures(obj, textures, baked.carried)
        slots = gltf_textures(textures, baked.carried)
    return SceneMaps(baked, slots, {**baked.maps.notes, "time_s": time.perf_counter() - t,
                                    "own_uvs": atlas is not None, "atlas_note": note})
