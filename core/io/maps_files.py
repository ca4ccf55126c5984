"""The base mesh with its maps as glTF, for engines: UVs, normals (the maps' unit directions,
along which the heights point), tangents, and a material with the height map as
``KHR_materials_displacement`` (a 16-bit texture, h = offset + factor · value, as NVIDIA's
RTX Mega Geometry samples read it), the normal map as ``normalTexture`` and the source's
textures carried onto the atlas in glTF's slots. Row 0 of our arrays is v = 0 (the bottom);
glTF's v runs down the image, so v is flipped here (the images' rows: ``core.io.images``).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..mesh.float32_origin import node_translation, relative
from ..maps import Maps, unit_directions, vertex_tangents
from ..micro.micromesh import MicroMesh
from .gltf import Builder
from .images import HeightCode
from .micromesh_export import Y_UP


DISPLACEMENT = "KHR_materials_displacement"


def base_gltf(path: Path, mm: MicroMesh, maps: Maps, normal_uri: str, height_uri: str,
              code: HeightCode, y_up: bool = False, textures: dict | None = None
              ) -> list[tuple[Path, bytes]]:
    """``path`` (.gltf) and its ``.bin``: the base split at the atlas' seams, with UVs,
    normals and a material whose displacement is the 16-bit ``height_uri`` read through
    ``code``, whose ``normalTexture`` is ``normal_uri`` and whose other textures are
    ``textures`` ({"baseColorTexture" | "metallicRoughnessTexture" | "emissiveTexture": uri},
    the source's textures carried onto the atlas) (``y_up``: Blender's Z-up turned into
    glTF's Y-up, as ``micromesh_export`` does)."""
    at = maps.atlas
    rot = Y_UP.T if y_up else np.eye(3)
    g = Builder()
    idx = g.accessor(at.faces.reshape(-1), "<u4", "indices", target=34963)
    local, origin = relative(mm.base.vertices[at.vertex] @ rot)    # far: a node translation
    pos = g.accessor(local, "<f4", "positions", target=34962, bounds=True)
    nrm = g.accessor(unit_directions(mm)[at.vertex] @ rot, "<f4", "normals", target=34962)
    tan = vertex_tangents(mm, at)
    tan = g.accessor(np.concatenate([tan[:, :3] @ rot, tan[:, 3:]], 1), "<f4", "tangents",
                     target=34962)
    # glTF's v runs down the image, ours up: v is flipped, the tangent frame is not (the
    # normal map's +Y is "up in the image" in both, as Blender's own glTF exporter keeps it)
    uv = g.accessor(np.stack([at.uv[:, 0], 1.0 - at.uv[:, 1]], 1), "<f4", "uvs", target=34962)
    doc, blob = g.finish(path.with_suffix(".bin").name)
    textures = dict(textures or {})
    unknown = set(textures) - {"baseColorTexture", "metallicRoughnessTexture", "emissiveTexture"}
    if unknown:
        raise ValueError(f"base_gltf: unknown texture slots {sorted(unknown)}")
    slots = list(textures)
    doc["images"] = [{"uri": normal_uri}, {"uri": height_uri}] + \
        [{"uri": textures[k]} for k in slots]
    doc["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071}]
    doc["textures"] = [{"source": i, "sampler": 0} for i in range(len(doc["images"]))]
    pbr = {"metallicFactor": 0.0}
    material = {"name": f"{path.stem}_material", "normalTexture": {"index": 0},
                "extensions": {DISPLACEMENT: {"displacementGeometryTexture": {"index": 1},
                                              "displacementGeometryFactor": code.factor,
                                              "displacementGeometryOffset": code.offset}}}
    for i, slot in enumerate(slots, 2):
        if slot == "emissiveTexture":
            material.update(emissiveTexture={"index": i}, emissiveFactor=[1.0, 1.0, 1.0])
        else:
            pbr[slot] = {"index": i}
    if "metallicRoughnessTexture" in textures:
        pbr.update(metallicFactor=1.0, roughnessFactor=1.0)
    doc["materials"] = [{**material, "pbrMetallicRoughness": pbr}]
    doc["extensionsUsed"] = [DISPLACEMENT]
    doc["meshes"] = [{"name": path.stem, "primitives": [{
        "attributes": {"POSITION": pos, "NORMAL": nrm, "TANGENT": tan, "TEXCOORD_0": uv},
        "indices": idx, "material": 0, "mode": 4}]}]
    doc["nodes"] = [{"mesh": 0, "name": path.stem, **node_translation(origin)}]
    doc["scenes"], doc["scene"] = [{"nodes": [0]}], 0
    return [(path.with_suffix(".bin"), blob), (path, json.dumps(doc, indent=1).encode())]
