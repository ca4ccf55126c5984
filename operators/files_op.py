"""File ▸ Export / Import ▸ Micro-Mesh: a result object to files other tools read (the formats
of ``core.io.formats``: the micro-mesh as glTF + ``.bary``, or the base with its maps as glTF,
USD and images), and micro-mesh files (ours, micromesh-tools', NVIDIA's) to a base and a
result object with the attributes a construction writes."""
from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ..core.io import formats
from ..core.io.micromesh_export import Y_UP, ExportError
from ..core.io.micromesh_import import MicromeshFileError, read_micromesh
from ..core.io.output_set import OutputSet
from ..core.micro.metrics import mmt_formula_bytes
from ..core.workflow import write_formats
from ..core.workflow.outcome import Outcome
from . import base_ops, bl_mesh, writeback
from .maps_object import maps_of

Y_UP_HELP = "glTF is Y-up, Blender Z-up: convert as Blender's own glTF exporter does"


def result_object(context) -> bpy.types.Object | None:
    """The active object if it holds a micro-mesh, else the result built from the active object
    (a source or a base) or from the panel's source."""
    obj = context.active_object
    if obj is not None and obj.get(writeback.DATA_KEY) is not None:
        return obj
    keys = {o for o in (obj, base_ops.source_object(context)) if o is not None}
    for cand in bpy.data.objects:
        if cand.get(writeback.DATA_KEY) is not None and keys & {cand.micromesh_source,
                                                               cand.micromesh_base}:
            return cand
    return None


MAPS = "MAPS"


def _format_items(self, context):
    """The export's formats, from the table: each micro-mesh format, and the maps' formats
    together (the base with its height and normal maps). (Blender keeps no reference to
    the strings: the list is kept here.)"""
    global _ITEMS
    _ITEMS = [(f.key.upper(), f.label, f"NAME{', NAME'.join(f.suffixes)}")
              for f in formats.group(formats.MICROMESH)] + [
        (MAPS, "Base + height map (glTF, USD, PNG, EXR)",
         "The base with the height map Bake Maps fitted: " + ", ".join(
             f"NAME{f.suffixes[0]}" for f in formats.group(formats.MAPS)))]
    return _ITEMS


_ITEMS: list = []


class MICROMESH_OT_export(bpy.types.Operator, ExportHelper):
    """Write the micro-mesh as glTF 2.0 with NV_displacement_micromap and a .bary file, for
    micromesh-tools, NVIDIA's tools and ray tracers; or the base with its height map (Bake
    Maps) as glTF with KHR_materials_displacement and as USD, for renderers"""
    bl_idname = "micromesh.export"
    bl_label = "Export Micro-Mesh"
    filename_ext = ".gltf"
    filter_glob: StringProperty(default="*.gltf;*.glb", options={"HIDDEN"})
    container: EnumProperty(name="Format", items=_format_items)
    values: EnumProperty(name="Values", items=(
        ("r11", "11-bit packed", "eR11_unorm_packed_align32: what hardware and tools expect"),
        ("float", "32-bit float", "eR32_sfloat: larger, no quantisation")), default="r11")
    order: EnumProperty(name="Layout", items=(
        ("bird", "Bird curve", "The order ray-tracing hardware takes"),
        ("umajor", "U-major", "Row by row (micromesh-tools reads only this)")), default="bird")
    y_up: BoolProperty(name="+Y Up", default=True, description=Y_UP_HELP)

    @classmethod
    def poll(cls, context):
        return result_object(context) is not None

    def check(self, context):
        ext = ".glb" if self.container == "GLB" else ".gltf"
        p = Path(self.filepath)
        want = str(p.with_suffix(ext)) if p.suffix.lower() in (".gltf", ".glb") else \
            self.filepath + ext
        changed, self.filepath = want != self.filepath, want
        return changed

    def execute(self, context):
        self.check(context)
        obj = result_object(context)
        path = Path(self.filepath)
        try:
            out = writeback.load_outcome(obj)
            product = formats.Product(out.micromesh, out.bounds, y_up=self.y_up,
                                      values=self.values, layout=self.order)
            if self.container == MAPS:
                src = obj.micromesh_source or obj
                product.maps = maps_of(bpy.data.objects.get(f"{src.name}_maps"))
                if product.maps is None:
                    raise ValueError(f"'{src.name}' has no maps: Bake Maps first")
                chosen = formats.group(formats.MAPS)
            else:
                chosen = [formats.FORMATS[self.container.lower()]]
            written = _write(chosen, product, path.parent, path.stem)
        except (ExportError, ValueError, OSError) as e:
            self.report({"ERROR"}, f"Export failed: {e}")
            return {"CANCELLED"}
        size = sum(written.values())
        self.report({"INFO"}, f"Wrote {', '.join(written)} ({size:,} B)")
        return {"FINISHED"}


def _write(chosen: list, product: formats.Product, folder: Path, name: str) -> dict:
    """The ``chosen`` formats' files in ``folder`` as one set (``core.workflow.write_formats``,
    each under a temporary name first, then all renamed; none left where one fails);
    {file name: bytes}."""
    suffixes = [s for f in chosen for s in f.suffixes]
    out = OutputSet(folder, name, suffixes[::-1],      # the first format's main file last
                    [s for f in chosen for s in f.optional])
    with out:
        records = write_formats(chosen, product, out)
        out.commit()
    return {f"{name}{s}": n for r in records.values() for s, n in r["bytes_by_file"].items()}


class MICROMESH_OT_import(bpy.types.Operator, ImportHelper):
    """Read a micro-mesh glTF (.gltf/.glb + .bary) into a base object and a result object with
    the attributes of a construction, to inspect, compare or re-export it"""
    bl_idname = "micromesh.import_file"
    bl_label = "Import Micro-Mesh"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".gltf"
    filter_glob: StringProperty(default="*.gltf;*.glb", options={"HIDDEN"})
    y_up: BoolProperty(name="+Y Up", default=True, description=Y_UP_HELP)

    def execute(self, context):
        path = Path(self.filepath)
        try:
            f = read_micromesh(path)
            mm = f.micromesh()
        except (MicromeshFileError, OSError) as e:
            self.report({"ERROR"}, f"Cannot import {path.name}: {e}")
            return {"CANCELLED"}
        if self.y_up:   # glTF's Y-up back to Blender's Z-up (Y_UP is orthonormal)
            mm = mm.transformed(Y_UP.T)
        metrics = {"base_faces": int(mm.base.n_faces), "micro_triangles": mm.topology.n_triangles,
                   "micro_vertices": mm.n_vertices,
                   "bytes_mmt": mmt_formula_bytes(mm.levels, mm.base.n_vertices),
                   "levels_hist": np.bincount(mm.levels).tolist(), "warnings": f.warnings,
                   "file": str(path)}
        # new objects only: an import never replaces a construction of the same name
        base_name, name = _unused(f"{path.stem}_base"), _unused(f"{path.stem}_micromesh")
        base, origin = bl_mesh.placed_mesh(base_name, mm.base.vertices, mm.base.faces)
        base_obj, _ = bl_mesh.object_with_mesh(context, base_name, base, None,
                                               reuse=lambda o: False)
        bl_mesh.place(base_obj, origin)
        base_obj.display_type = "WIRE"
        obj = writeback.write_result(context, None, base_obj, Outcome(mm, None, metrics,
                                                                      method="import"), name=name)
        for o in context.view_layer.objects:
            o.select_set(o in (obj, base_obj))
        context.view_layer.objects.active = obj
        for w in f.warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"Imported {obj.name}: {mm.base.n_faces:,} base triangles, "
                              f"{mm.topology.n_triangles:,} micro-triangles")
        return {"FINISHED"}


def _unused(name: str) -> str:
    """``name``, or ``name.001``, ``name.002``, … : the first no object has."""
    out, k = name, 1
    while out in bpy.data.objects:
        out, k = f"{name}.{k:03d}", k + 1
    return out


def _menu_export(self, context):
    self.layout.operator(MICROMESH_OT_export.bl_idname,
                         text="Micro-Mesh (.gltf/.glb + .bary, or base + height map)")


def _menu_import(self, context):
    self.layout.operator(MICROMESH_OT_import.bl_idname, text="Micro-Mesh (.gltf/.glb + .bary)")


CLASSES = (MICROMESH_OT_export, MICROMESH_OT_import)
MENUS = ((bpy.types.TOPBAR_MT_file_export, _menu_export),
         (bpy.types.TOPBAR_MT_file_import, _menu_import))
