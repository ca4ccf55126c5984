"""Write a construction result into the scene and read it back from a saved ``.blend``.

- the result object ``<source>_micromesh``: the displaced tessellation as a real mesh with
  per-face ``micromesh_base_face`` / ``micromesh_level``, per-vertex ``micromesh_displacement``
  / ``micromesh_direction``, level colours (``micromesh_level_color``, the active colour) and a
  Geometry Nodes modifier that scales the displacement live (``preview``);
- the base object: optimised positions, per-face ``micromesh_level`` and
  ``micromesh_edge_flags``, per-vertex ``micromesh_direction``;
- the complete micro-mesh (base, directions, levels, displacements, bounds) as compressed
  ``.npz`` bytes (``core.workflow.outcome.pack``) in the result object's ``micromesh_data`` property, settings / metrics /
  history as JSON properties, so it survives saving and can be exported without re-running.
"""
from __future__ import annotations

import json

import bpy
import numpy as np

from ..core.report.level_colors import LEVEL_COLORS as CORE_LEVEL_COLORS
from ..core.micro.micromesh import MicroMesh
from ..core.workflow.outcome import Outcome, jsonable, pack, unpack
from . import bl_mesh
from .preview import add_preview_modifier

DATA_KEY = "micromesh_data"
REPORT_KEY = "micromesh_report_png"
# The colours of levels 0..5 (the report's, core.report.level_colors), linear RGBA.
LEVEL_COLORS = np.c_[CORE_LEVEL_COLORS[:6], np.ones(6)].astype(np.float32)


# ---------------------------------------------------------------- attributes
def _attr(mesh, name: str, kind: str, domain: str, values: np.ndarray, key: str = "value"):
    if name in mesh.attributes:
        mesh.attributes.remove(mesh.attributes[name])
    a = mesh.attributes.new(name, kind, domain)
    a.data.foreach_set(key, np.ascontiguousarray(values).reshape(-1))
    return a


def read_attr(mesh, name: str, key: str = "value", dtype=np.float64, width: int = 1) -> np.ndarray:
    """An attribute of ``mesh`` as an array ((n,) or (n, width))."""
    a = mesh.attributes[name]
    out = np.empty(len(a.data) * width, dtype=np.int32 if dtype in (np.int32, np.int64, int) else np.float32)
    a.data.foreach_get(key, out)
    out = out.astype(dtype)
    return out.reshape(-1, width) if width > 1 else out


def level_colors(levels: np.ndarray) -> np.ndarray:
    return LEVEL_COLORS[np.clip(np.asarray(levels, dtype=np.int64), 0, 5)]


# ---------------------------------------------------------------- persistence
def store_bytes(obj, key: str, data: bytes) -> None:
    """``obj[key] = data``, safely: assigning bytes to an ID property that already holds
    bytes keeps them only up to the first zero byte (bpy 4.2-5.0), so the old one goes first;
    the stored value is read back and compared."""
    if key in obj:
        del obj[key]
    obj[key] = data
    if bytes(obj[key]) != data:
        raise RuntimeError(f"Blender stored {len(bytes(obj[key]))} of {len(data)} bytes of "
                           f"'{key}' on '{obj.name}'")


def load_outcome(obj: bpy.types.Object) -> Outcome:
    """The complete micro-mesh stored on a result object (after reopening a ``.blend``)."""
    if DATA_KEY not in obj:
        raise ValueError(f"object '{obj.name}' holds no micro-mesh (run Construct first)")
    mm, bounds = unpack(obj[DATA_KEY])
    loads = lambda k: json.loads(obj.get(k, "{}"))  # noqa: E731
    return Outcome(mm, bounds, loads("micromesh_metrics"), loads("micromesh_settings"),
                   loads("micromesh_history"), obj.get("micromesh_method", ""))


# ---------------------------------------------------------------- write-back
def write_result(context, source: bpy.types.Object, base_obj: bpy.types.Object | None,
                 out: Outcome, name: str | None = None) -> bpy.types.Object:
    """Create (or replace) ``<source>_micromesh`` and update the base object; returns the result."""
    mm = out.micromesh
    tess = mm.tessellate()
    name = name or f"{source.name}_micromesh"
    mesh, origin = bl_mesh.placed_mesh(name, tess.vertices, tess.triangles)   # far: centred
    levels = mm.levels[tess.triangle_face]
    _attr(mesh, "micromesh_base_face", "INT", "FACE", tess.triangle_face.astype(np.int32))
    _attr(mesh, "micromesh_level", "INT", "FACE", levels.astype(np.int32))
    _attr(mesh, "micromesh_displacement", "FLOAT", "POINT", mm.displacements.astype(np.float32))
    _attr(mesh, "micromesh_direction", "FLOAT_VECTOR", "POINT",
          mm.micro_vertex_directions().astype(np.float32), key="vector")
    corner_colors = np.repeat(level_colors(levels), 3, axis=0)
    col = _attr(mesh, "micromesh_level_color", "FLOAT_COLOR", "CORNER", corner_colors, key="color")
    mesh.color_attributes.active_color = col
    mesh.color_attributes.render_color_index = mesh.color_attributes.active_color_index

    obj, reused = bl_mesh.object_with_mesh(context, name, mesh, source,
                                           reuse=lambda o: o.get(DATA_KEY) is not None)
    if reused or origin is not None:   # the tessellation is in world space
        bl_mesh.place(obj, origin)
    obj.micromesh_source = source
    obj.micromesh_base = base_obj
    store_bytes(obj, DATA_KEY, pack(out))
    obj["micromesh_metrics"] = json.dumps(jsonable(out.metrics))
    obj["micromesh_settings"] = json.dumps(jsonable(out.settings))
    obj["micromesh_history"] = json.dumps(jsonable(out.history))
    obj["micromesh_method"] = out.method
    if out.report_png:
        store_bytes(obj, REPORT_KEY, out.report_png)
        obj["micromesh_report"] = json.dumps(jsonable(out.report))
    add_preview_modifier(obj)
    if base_obj is not None:
        write_base(base_obj, mm)
    return obj


def write_base(base_obj: bpy.types.Object, mm: MicroMesh) -> None:
    """Optimised positions and the per-face / per-vertex micro-mesh attributes on the base."""
    inv = np.linalg.inv(np.array(base_obj.matrix_world, dtype=np.float64))
    local = mm.base.vertices @ inv[:3, :3].T + inv[:3, 3]
    mesh = base_obj.data
    same = (len(mesh.vertices) == mm.base.n_vertices and len(mesh.polygons) == mm.base.n_faces
            and all(len(p.vertices) == 3 for p in mesh.polygons))
    if same:
        mesh.calc_loop_triangles()
        f = np.empty(3 * len(mesh.loop_triangles), np.int32)
        mesh.loop_triangles.foreach_get("vertices", f)
        same = np.array_equal(f.reshape(-1, 3), mm.base.faces)
    if same:
        mesh.vertices.foreach_set("co", local.astype(np.float32).reshape(-1))
    else:  # the artist's base had n-gons: replace it with the triangulated base
        new = bl_mesh.arrays_to_mesh(mesh.name, local, mm.base.faces)
        base_obj.data = new
        if mesh.users == 0:
            bpy.data.meshes.remove(mesh)
        mesh = new
    _attr(mesh, "micromesh_level", "INT", "FACE", mm.levels.astype(np.int32))
    _attr(mesh, "micromesh_edge_flags", "INT", "FACE", mm.topology.flags.astype(np.int32))
    dir_local = mm.directions @ inv[:3, :3].T
    _attr(mesh, "micromesh_direction", "FLOAT_VECTOR", "POINT", dir_local.astype(np.float32),
          key="vector")
    col = _attr(mesh, "micromesh_level_color", "FLOAT_COLOR", "CORNER",
                np.repeat(level_colors(mm.levels), 3, axis=0), key="color")
    mesh.color_attributes.active_color = col
    mesh.update()


def base_levels(base_obj: bpy.types.Object, tri_polygon: np.ndarray) -> np.ndarray | None:
    """Per-triangle levels from the base's ``micromesh_level`` face attribute (None if absent)."""
    mesh = base_obj.data
    a = mesh.attributes.get("micromesh_level")
    if a is None or a.domain != "FACE":
        return None
    lv = read_attr(mesh, "micromesh_level", dtype=np.int64)
    return np.clip(lv[tri_polygon], 0, 5)
