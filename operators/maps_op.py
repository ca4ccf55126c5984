"""Bake Maps: height and normal maps of a result on a UV atlas of its base (``core.maps``), and
``<source>_maps``: the base with those UVs and a Geometry Nodes modifier that subdivides it and
displaces it by the height map along its interpolated directions, so Cycles and EEVEE render
the micro-detail from a texture. Images are packed into the ``.blend`` (``batch.py --maps``
also writes them as files)."""
from __future__ import annotations

from functools import partial

import bpy
import numpy as np
from bpy.props import IntProperty

from ..core.maps import Maps, unit_directions
from ..core.micromesh import MicroMesh
from . import bl_mesh, job, source_texture, writeback
from .maps_work import bake_with_textures, own_atlas
from .images import image
from .files_op import result_object

GROUP = "MicroMesh Height Map"
MODIFIER = "MicroMesh Height"


def maps_object(context, source, mm: MicroMesh, maps: Maps, name: str) -> bpy.types.Object:
    """``name``: the base split at the atlas' seams, with UVs, unit directions, the height
    modifier (level: the result's finest) and a material holding the normal map."""
    at = maps.atlas
    mesh, origin = bl_mesh.placed_mesh(name, mm.base.vertices[at.vertex], at.faces)
    uv = mesh.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", at.corner_uv.reshape(-1).astype(np.float32))
    a = mesh.attributes.new("micromesh_unit_direction", "FLOAT_VECTOR", "POINT")
    a.data.foreach_set("vector", unit_directions(mm)[at.vertex].astype(np.float32).reshape(-1))
    obj, reused = bl_mesh.object_with_mesh(context, name, mesh, source,
                                           reuse=lambda o: o.modifiers.get(MODIFIER) is not None)
    if reused or origin is not None:   # world space, centred where far from the origin
        bl_mesh.place(obj, origin)
    height = image(f"{name}_height", maps.height)
    normal = image(f"{name}_normal", maps.normal)
    mod = obj.modifiers.get(MODIFIER) or obj.modifiers.new(MODIFIER, "NODES")
    mod.node_group = _group(f"{GROUP} {name}", height)
    mod[_input(mod.node_group, "Level")] = int(mm.levels.max(initial=0))
    obj.data.materials.clear()
    obj.data.materials.append(_material(f"{name}_material", normal))
    return obj


def _input(ng, name: str) -> str:
    return next(i.identifier for i in ng.interface.items_tree
                if getattr(i, "in_out", "") == "INPUT" and i.name == name)


def _group(name: str, height: bpy.types.Image) -> bpy.types.NodeTree:
    """Subdivide (simple) → position += normalize(direction) · height(UV) · Strength."""
    ng = bpy.data.node_groups.get(name) or bpy.data.node_groups.new(name, "GeometryNodeTree")
    ng.nodes.clear()
    ng.interface.clear()
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    lv = ng.interface.new_socket("Level", in_out="INPUT", socket_type="NodeSocketInt")
    lv.default_value, lv.min_value, lv.max_value = 3, 0, 6
    st = ng.interface.new_socket("Strength", in_out="INPUT", socket_type="NodeSocketFloat")
    st.default_value = 1.0
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n, link = ng.nodes, ng.links.new
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    sub = n.new("GeometryNodeSubdivideMesh")
    uv = n.new("GeometryNodeInputNamedAttribute")
    uv.data_type, uv.inputs["Name"].default_value = "FLOAT_VECTOR", "UVMap"
    tex = n.new("GeometryNodeImageTexture")
    tex.interpolation, tex.extension = "Linear", "EXTEND"
    tex.inputs["Image"].default_value = height
    sep = n.new("FunctionNodeSeparateColor")
    d = n.new("GeometryNodeInputNamedAttribute")
    d.data_type, d.inputs["Name"].default_value = "FLOAT_VECTOR", "micromesh_unit_direction"
    unit = n.new("ShaderNodeVectorMath")
    unit.operation = "NORMALIZE"
    mul = n.new("ShaderNodeMath")
    mul.operation = "MULTIPLY"
    scale = n.new("ShaderNodeVectorMath")
    scale.operation = "SCALE"
    setpos = n.new("GeometryNodeSetPosition")
    link(gin.outputs["Geometry"], sub.inputs["Mesh"])
    link(gin.outputs["Level"], sub.inputs["Level"])
    link(uv.outputs["Attribute"], tex.inputs["Vector"])
    link(tex.outputs["Color"], sep.inputs["Color"])
    link(sep.outputs[0], mul.inputs[0])
    link(gin.outputs["Strength"], mul.inputs[1])
    link(d.outputs["Attribute"], unit.inputs[0])
    link(unit.outputs["Vector"], scale.inputs[0])
    link(mul.outputs[0], scale.inputs["Scale"])
    link(sub.outputs["Mesh"], setpos.inputs["Geometry"])
    link(scale.outputs["Vector"], setpos.inputs["Offset"])
    link(setpos.outputs["Geometry"], gout.inputs["Geometry"])
    return ng


def _material(name: str, normal: bpy.types.Image) -> bpy.types.Material:
    """Principled BSDF, and the normal map ready beside it: connect it to the BSDF's Normal for
    low subdivision levels or for an engine (on the fully subdivided mesh the geometry already
    carries the detail, and the map would tilt it twice)."""
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):      # 5.0: materials always have nodes
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    for node in [x for x in nodes if x.type in ("TEX_IMAGE", "NORMAL_MAP", "UVMAP")]:
        nodes.remove(node)
    tex = nodes.new("ShaderNodeTexImage")
    tex.image, tex.label = normal, "Micro-mesh normal map"
    nmap = nodes.new("ShaderNodeNormalMap")
    nmap.uv_map = "UVMap"
    mat.node_tree.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    return mat


class MICROMESH_OT_bake_maps(bpy.types.Operator):
    """Bake height and normal maps of the micro-mesh on a UV atlas of its base, and make an
    object that renders the detail from them (Cycles and EEVEE)"""
    bl_idname = "micromesh.bake_maps"
    bl_label = "Bake Maps"
    bl_options = {"REGISTER", "UNDO"}
    resolution: IntProperty(name="Resolution", default=2048, min=64, max=8192)

    @classmethod
    def poll(cls, context):
        return result_object(context) is not None and job.active_job() is None

    def _work(self, context):
        res = result_object(context)
        out = writeback.load_outcome(res)
        src = res.micromesh_source
        self._result, self._mm = res, out.micromesh
        self._textures = source_texture.read(src) if src is not None else None
        atlas, self._atlas_note = own_atlas(res.micromesh_base, out.micromesh, self.resolution)
        self._own_uvs = atlas is not None
        return partial(bake_with_textures, out.micromesh, self.resolution, self._textures,
                       atlas=atlas)

    def _finish(self, context, baked):
        maps, carried = baked.maps, baked.carried
        src = self._result.micromesh_source or self._result
        obj = maps_object(context, src, self._mm, maps, f"{src.name}_maps")
        what = "height and normal maps" + (
            f" on '{self._result.micromesh_base.name}''s own UVs" if self._own_uvs else "")
        if self._atlas_note:
            self.report({"WARNING"}, self._atlas_note)
        if carried:
            source_texture.carry_textures(obj, self._textures, carried)
            names = ", ".join(t.socket.lower() for t in self._textures.images)
            what += f", and '{src.name}''s textures ({names}) carried onto their atlas"
        self.report({"INFO"}, f"{obj.name}: {self.resolution}² {what}")
        return {"FINISHED"}

    def execute(self, context):
        work = self._work(context)
        return self._finish(context, work(lambda p: None, lambda: False))

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        return {"RUNNING_MODAL"} if job.start_modal(self, context, self._work(context)) \
            else {"CANCELLED"}

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            self._job.cancel()
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        state = self._job.poll()
        context.workspace.status_text_set(state.status_text())
        if not state.done:
            return {"PASS_THROUGH"}
        job.end_modal(self, context)
        if state.cancelled or state.error:
            self.report({"WARNING"} if state.cancelled else {"ERROR"},
                        "Baking cancelled; nothing was changed" if state.cancelled
                        else state.error)
            return {"CANCELLED"}
        return self._finish(context, state.result)


CLASSES = (MICROMESH_OT_bake_maps,)
