"""Operators of the topology pre-pass: make a base mesh, place cameras (checking the base:
``check_op``); the source and base objects they work on."""
from __future__ import annotations

import bpy
import numpy as np

from ..core.base import builders
from ..core.mesh.trimesh import MeshError, TriMesh
from . import bl_decimate, bl_mesh, cameras_io  # noqa: F401  (bl_decimate: Blender's builder)
from .scene_settings import panel_settings


def source_object(context) -> bpy.types.Object | None:
    """The source: the scene setting, else the active mesh (a base/result's source if linked)."""
    s = context.scene.micromesh
    if s.source is not None:
        return s.source
    obj = context.active_object
    if obj is None or obj.type != "MESH":
        return None
    return obj.micromesh_source or obj


def base_object(context) -> bpy.types.Object | None:
    s = context.scene.micromesh
    if s.base is not None:
        return s.base
    obj = context.active_object
    if obj is not None and obj.type == "MESH" and obj.micromesh_source is not None \
            and not obj.get("micromesh_data"):
        return obj
    return None


def base_arrays(base_obj: bpy.types.Object) -> tuple[TriMesh, np.ndarray]:
    """World-space triangles of the base object's own mesh (no modifiers: it is what gets
    written back) and the polygon of each triangle."""
    mesh = base_obj.data
    v, f = bl_mesh.mesh_arrays(mesh)
    if len(f) == 0:
        raise MeshError(f"base '{base_obj.name}' has no faces")
    poly = np.empty(len(mesh.loop_triangles), np.int32)
    mesh.loop_triangles.foreach_get("polygon_index", poly)
    m = np.array(base_obj.matrix_world, dtype=np.float64)
    return TriMesh(v @ m[:3, :3].T + m[:3, 3], f), poly.astype(np.int64)


def link_base(context, src: bpy.types.Object, vertices: np.ndarray,
              faces: np.ndarray, uv: np.ndarray | None = None) -> bpy.types.Object:
    """``<source>_base`` holding the world-space triangles (an earlier base of the same source
    is reused), shown as wire, placed at their float32 origin where they are far from the
    world's (``bl_mesh.placed_mesh``); ``uv`` (faces, 3, 2): a UV map "UVMap" at their
    corners."""
    name = f"{src.name}_base"
    mesh, origin = bl_mesh.placed_mesh(name, vertices, faces)
    if uv is not None:
        mesh.uv_layers.new(name="UVMap").data.foreach_set(
            "uv", np.asarray(uv, dtype=np.float32).reshape(-1))
    obj, reused = bl_mesh.object_with_mesh(context, name, mesh, src,
                                           reuse=lambda o: o.micromesh_source == src)
    if reused or origin is not None:  # the arrays are in world space
        bl_mesh.place(obj, origin)
    obj.micromesh_source = src
    obj.display_type = "WIRE"
    return obj


class MICROMESH_OT_make_base(bpy.types.Operator):
    """Make a triangulated low-poly base mesh from the source: a faithful edge collapse that
    keeps the topology, or Blender's Decimate modifier"""
    bl_idname = "micromesh.make_base"
    bl_label = "Make Base Mesh"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return source_object(context) is not None

    def execute(self, context):
        s = context.scene.micromesh
        src = source_object(context)
        notes = []
        uv = None              # Blender's Decimate carries the source's UVs: the base keeps them
        builder = builders.get(s.base_method.lower())     # the table of base builders
        try:
            if builder.takes == builders.ARRAYS:
                base, notes = self._arrays(context, src, builder)
            else:
                kw = dict(target_faces=s.target_faces) if s.decimate_mode == "TARGET" else \
                    dict(ratio=s.ratio if s.decimate_mode == "RATIO" else 1 / 32)
                base, uv = builder.build(     # the panel's own target: no settings needed
                    src, None,
                    symmetry=None if s.symmetry == "NONE" else s.symmetry,
                    vertex_group=s.vertex_group, vertex_group_factor=s.vertex_group_factor,
                    invert_vertex_group=s.invert_vertex_group, **kw)
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        obj = link_base(context, src, base.vertices, base.faces, uv)
        s.source, s.base = src, obj
        for line in notes:
            self.report({"WARNING"}, line)
        self.report({"INFO"}, f"Base mesh '{obj.name}': {base.n_faces} triangles, "
                              f"{base.n_vertices} vertices")
        return {"FINISHED"}

    @staticmethod
    def _arrays(context, src, builder) -> tuple[TriMesh, list[str]]:
        """A core builder with the panel's targets, mapped as Construct maps them; the
        builder's warnings and notes for the report."""
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            built = builder.build(bl_mesh.mesh_to_arrays(src), panel_settings(context.scene),
                                  lambda f: wm.progress_update(int(100 * f)))
        finally:
            wm.progress_end()
        return built.mesh, built.warnings + built.report["notes"]


class MICROMESH_OT_place_cameras(bpy.types.Operator):
    """Place camera objects on a Fibonacci sphere around the source (replacing the previous set)"""
    bl_idname = "micromesh.place_cameras"
    bl_label = "Place Cameras"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return source_object(context) is not None

    def execute(self, context):
        s = context.scene.micromesh
        src = source_object(context)
        try:
            ref = bl_mesh.mesh_to_arrays(src)
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        coll = cameras_io.place_cameras(context.scene, ref, s.camera_count, s.camera_radius,
                                        s.camera_fov, s.camera_collection)
        s.camera_collection = coll
        s.source = src
        self.report({"INFO"}, f"{s.camera_count} cameras in '{coll.name}'")
        return {"FINISHED"}


CLASSES = (MICROMESH_OT_make_base, MICROMESH_OT_place_cameras)
