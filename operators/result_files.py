"""A result's files beside its ``.blend`` (``batch.py``): the micro-mesh as glTF + ``.bary``,
the run report, and the maps for engines, each written into the result's output set
(``core.io.output_set``) under its temporary name."""
from __future__ import annotations

import json
import time

import numpy as np

from ..core.io.maps_files import base_gltf, png
from ..core.io.micromesh_export import micromesh_files
from ..core.maps import rebuild_error
from . import images, maps_op, maps_work, source_texture, writeback
from .sources import export_y_up


def write_export(outcome, source, container: str, values: str, layout: str, out) -> dict:
    """``NAME.gltf`` + ``.bin`` + ``.bary`` (or ``NAME.glb``) in the input file's coordinates
    (what Blender's importers turned Z-up goes back to Y-up); what the metrics record."""
    files, rep = micromesh_files(out.final(f".{container}"), outcome.micromesh, outcome.bounds,
                                 value_format=values, layout=layout, y_up=export_y_up(source))
    for path, data in files:
        out.temp(path.suffix).write_bytes(data)
    return {"files": [p.name for p, _ in files], "bytes": rep.bytes, "values": values,
            "layout": layout, "quantization_max": rep.quantization_max,
            "quantization_rms": rep.quantization_rms}


def write_report(outcome, out) -> None:
    """``NAME.report.png`` and ``NAME.report.json`` (when the run made a report)."""
    if outcome.report_png:
        out.temp(".report.png").write_bytes(outcome.report_png)
        out.temp(".report.json").write_text(json.dumps(writeback._jsonable(outcome.report),
                                                       indent=1))


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


def write_maps(context, outcome, source, resolution: int, out, progress,
               base_obj=None) -> dict:
    """Height and normal maps: ``<source>_maps`` in the scene (images packed) and, for
    engines, ``NAME_height.exr``, ``NAME_normal.png`` (16-bit; :func:`engine_normal_map`) and
    ``NAME_base.gltf`` (UVs, normals, tangents, the normal map); where the source's material
    has textures, they are carried onto the atlas too (base colour, metallic and roughness,
    emission: the glTF's ``NAME_basecolor.png``, ``NAME_metallicroughness.png``,
    ``NAME_emissive.png``); how well
    the height map rebuilds the micro-mesh. On ``base_obj``'s own UV map where it has one that
    fits (``maps_work.own_atlas``), else a new atlas."""
    import bpy

    mm, name = outcome.micromesh, out.name
    t = time.perf_counter()
    textures = source_texture.read(source)
    atlas, note = maps_work.own_atlas(base_obj, mm, resolution)
    baked = maps_work.bake_with_textures(mm, resolution, textures, progress, lambda: False,
                                         atlas=atlas, base_normal=True)
    maps, carried = baked.maps, baked.carried
    obj = maps_op.maps_object(context, source, mm, maps, f"{source.name}_maps")
    img = images.image(f"{name}_height_file", maps.height, path=str(out.temp("_height.exr")))
    bpy.data.images.remove(img)
    out.temp("_normal.png").write_bytes(png(engine_normal_map(baked)))
    uris = {}
    if carried:
        source_texture.carry_textures(obj, textures, carried)
        for slot, pixels in gltf_textures(textures, carried).items():
            suffix = "_" + slot.replace("Texture", "").lower() + ".png"
            out.temp(suffix).write_bytes(png(np.clip(pixels, 0.0, 1.0), bits=8))
            uris[slot] = name + suffix
    for path, data in base_gltf(out.final("_base.gltf"), mm, maps, f"{name}_normal.png",
                                f"{name}_height.exr", y_up=export_y_up(source),
                                textures=uris):
        out.temp(path.name[len(name):]).write_bytes(data)
    err = rebuild_error(mm, maps)
    return {"resolution": resolution, "time_s": time.perf_counter() - t,
            "own_uvs": atlas is not None, "atlas_note": note,
            "rebuild_rms": float(np.sqrt((err ** 2).mean()) / mm.base.bbox_diagonal),
            "rebuild_max": float(err.max(initial=0.0) / mm.base.bbox_diagonal)}
