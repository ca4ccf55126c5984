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
from . import images, maps_op, source_texture, writeback
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


def write_maps(context, outcome, source, resolution: int, out, progress) -> dict:
    """Height and normal maps: ``<source>_maps`` in the scene (images packed) and, for
    engines, ``NAME_height.exr``, ``NAME_normal.png`` (16-bit) and ``NAME_base.gltf`` (UVs,
    normals, tangents, the normal map); where the source has a base-colour texture, it is
    carried onto the atlas too (``NAME_basecolor.png``, the glTF's base colour); how well the
    height map rebuilds the micro-mesh."""
    import bpy

    mm, name = outcome.micromesh, out.name
    t = time.perf_counter()
    texture = source_texture.read(source)
    maps, color = maps_op.bake_with_texture(mm, resolution, texture, progress, lambda: False)
    obj = maps_op.maps_object(context, source, mm, maps, f"{source.name}_maps")
    img = images.image(f"{name}_height_file", maps.height, path=str(out.temp("_height.exr")))
    bpy.data.images.remove(img)
    out.temp("_normal.png").write_bytes(png(maps.normal))
    color_uri = None
    if color is not None:
        tex = source_texture.make_image(f"{source.name}_maps_basecolor", color, texture)
        source_texture.link_base_color(obj.data.materials[0], tex)
        out.temp("_basecolor.png").write_bytes(png(np.clip(color, 0.0, 1.0), bits=8))
        color_uri = f"{name}_basecolor.png"
    for path, data in base_gltf(out.final("_base.gltf"), mm, maps, f"{name}_normal.png",
                                f"{name}_height.exr", y_up=export_y_up(source),
                                base_color_uri=color_uri):
        out.temp(path.name[len(name):]).write_bytes(data)
    err = rebuild_error(mm, maps)
    return {"resolution": resolution, "time_s": time.perf_counter() - t,
            "rebuild_rms": float(np.sqrt((err ** 2).mean()) / mm.base.bbox_diagonal),
            "rebuild_max": float(err.max(initial=0.0) / mm.base.bbox_diagonal)}
