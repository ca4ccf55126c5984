"""Check Base Mesh: report what in the base mesh will hurt the micro-mesh (``check``) and
select it in Edit Mode."""
from __future__ import annotations

import bpy
import numpy as np
from bpy.props import BoolProperty

from ..core.mesh.trimesh import TriMesh
from . import bl_mesh, check
from .base_ops import base_arrays, base_object


class MICROMESH_OT_check_base(bpy.types.Operator):
    """Report and select in Edit Mode what in the base mesh will hurt the micro-mesh"""
    bl_idname = "micromesh.check_base"
    bl_label = "Check Base Mesh"
    bl_options = {"REGISTER", "UNDO"}

    select: BoolProperty(name="Select Problems", default=True)

    @classmethod
    def poll(cls, context):
        return base_object(context) is not None

    def execute(self, context):
        s = context.scene.micromesh
        base_obj = base_object(context)
        src = base_obj.micromesh_source or s.source
        if base_obj.mode == "EDIT":
            bpy.ops.object.mode_set(mode="OBJECT")
        try:
            base, tri_poly = base_arrays(base_obj)
            ref = bl_mesh.mesh_to_arrays(src) if src is not None else None
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        rep = check.check_base(base, ref)
        s.check_report = "; ".join(rep.lines)
        if self.select:
            select_problems(context, base_obj, base, tri_poly, rep)
        level = {"WARNING"} if rep.n_problems else {"INFO"}
        self.report(level, f"{rep.n_problems} problems: " + "; ".join(rep.lines))
        return {"FINISHED"}


def _set_selection(mesh, vsel: np.ndarray, fsel: np.ndarray) -> None:
    """Select these vertices and faces (and the edges between selected vertices) of
    ``mesh``, through bmesh: with bpy 5.0.1 a mesh made by ``from_pydata`` or
    ``update(calc_edges=True)`` can carry a hidden ``.select_edge`` layer of the wrong type,
    and writing ``edges.foreach_set("select")`` into it kills the process."""
    import bmesh

    bm = bmesh.new()
    try:
        bm.from_mesh(mesh)
        bm.verts.ensure_lookup_table()
        bm.faces.ensure_lookup_table()
        for v, on in zip(bm.verts, vsel.tolist()):
            v.select = on
        for e in bm.edges:
            e.select = e.verts[0].select and e.verts[1].select
        for f, on in zip(bm.faces, fsel.tolist()):
            f.select = on
        bm.to_mesh(mesh)
    finally:
        bm.free()
    mesh.update()


def select_problems(context, obj, base: TriMesh, tri_poly: np.ndarray, rep: check.CheckReport):
    """Select the offending vertices, edges and faces of ``obj`` and enter Edit Mode."""
    mesh = obj.data
    vsel = np.zeros(len(mesh.vertices), bool)
    fsel = np.zeros(len(mesh.polygons), bool)
    faces = np.concatenate([rep.flipped_faces, rep.sliver_faces, rep.degenerate_faces])
    fsel[tri_poly[faces]] = True
    bad_edges = base.edges[rep.nonmanifold_edges]
    vsel[bad_edges.reshape(-1)] = True
    vsel[rep.valence_vertices] = True
    vsel[base.faces[faces].reshape(-1)] = True
    _set_selection(mesh, vsel, fsel)
    view_layer = context.view_layer
    if obj.name in view_layer.objects:
        for o in view_layer.objects.selected:
            o.select_set(False)
        view_layer.objects.active = obj
        obj.select_set(True)
        bpy.ops.object.mode_set(mode="EDIT")
        context.tool_settings.mesh_select_mode = (True, True, True)


CLASSES = (MICROMESH_OT_check_base,)
