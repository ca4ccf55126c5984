"""Files of the maps path, for engines: the normal map as a 16-bit PNG and the base mesh as a
glTF with UVs, normals (the maps' unit directions) and the normal map as its material's
``normalTexture`` (and the source's texture carried onto the atlas as its
``baseColorTexture``, where there is one); the height map's file is named in the material's
``extras``. Row 0 of our
arrays is v = 0 (the bottom); PNG rows and glTF UVs start at the top, so both are flipped here.
"""
from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import numpy as np

from ..float32_origin import node_translation, relative
from ..maps import Maps, unit_directions, vertex_tangents
from ..micromesh import MicroMesh
from .gltf import Builder
from .micromesh_export import Y_UP


def png(pixels: np.ndarray, bits: int = 16) -> bytes:
    """An RGB or RGBA PNG (``pixels`` (H, W, 3 or 4) in [0, 1], row 0 at the bottom) of 8 or
    16 bits per channel."""
    h, w, c = pixels.shape
    if c not in (3, 4) or bits not in (8, 16):
        raise ValueError(f"png: (H, W, 3|4) pixels and 8 or 16 bits, got {pixels.shape}, {bits}")
    top = (1 << bits) - 1
    q = np.rint(np.clip(pixels[::-1], 0.0, 1.0) * top).astype(">u2" if bits == 16 else np.uint8)
    raw = np.concatenate([np.zeros((h, 1), np.uint8), q.reshape(h, -1).view(np.uint8)], 1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + \
            struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">2I5B", w, h, bits, 2 if c == 3 else 6, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + chunk(b"IEND", b""))


def base_gltf(path: Path, mm: MicroMesh, maps: Maps, normal_uri: str, height_uri: str,
              y_up: bool = False, textures: dict | None = None
              ) -> list[tuple[Path, bytes]]:
    """``path`` (.gltf) and its ``.bin``: the base split at the atlas' seams, with UVs,
    normals and a material whose ``normalTexture`` is ``normal_uri`` and whose other textures
    are ``textures`` ({"baseColorTexture" | "metallicRoughnessTexture" | "emissiveTexture":
    uri}, the source's textures carried onto the atlas) (``y_up``: Blender's Z-up turned into
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
    doc["images"] = [{"uri": normal_uri}] + [{"uri": textures[k]} for k in slots]
    doc["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071}]
    doc["textures"] = [{"source": i, "sampler": 0} for i in range(len(doc["images"]))]
    pbr = {"metallicFactor": 0.0}
    material = {"name": f"{path.stem}_material", "normalTexture": {"index": 0}}
    for i, slot in enumerate(slots, 1):
        if slot == "emissiveTexture":
            material.update(emissiveTexture={"index": i}, emissiveFactor=[1.0, 1.0, 1.0])
        else:
            pbr[slot] = {"index": i}
    if "metallicRoughnessTexture" in textures:
        pbr.update(metallicFactor=1.0, roughnessFactor=1.0)
    doc["materials"] = [{**material, "pbrMetallicRoughness": pbr,
                         "extras": {"heightMap": height_uri,
                                    "heightMapMeaning": "signed distance along the "
                                    "interpolated vertex normals, world units"}}]
    doc["meshes"] = [{"name": path.stem, "primitives": [{
        "attributes": {"POSITION": pos, "NORMAL": nrm, "TANGENT": tan, "TEXCOORD_0": uv},
        "indices": idx, "material": 0, "mode": 4}]}]
    doc["nodes"] = [{"mesh": 0, "name": path.stem, **node_translation(origin)}]
    doc["scenes"], doc["scene"] = [{"nodes": [0]}], 0
    return [(path.with_suffix(".bin"), blob), (path, json.dumps(doc, indent=1).encode())]
