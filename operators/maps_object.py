"""``<source>_maps``: the base split at the atlas' seams, with its UVs and unit directions,
displaced by the height map as the Blender in hand renders displacement best.

- Blender 5.0 and later: Cycles' adaptive subdivision. A Subdivision modifier (simple, so
  the base triangles stay flat; adaptive, diced to a pixel) and the material's Displacement
  node (Displacement only), the height image sampled at the UVs and moved along the
  normalised interpolated direction: what a renderer does with a base and a height map.
  Cycles draws it; the viewport and EEVEE show the base.
- Blender 4.2-4.5: a Geometry Nodes modifier that subdivides the base (simple, the level the
  height map was fitted for) and displaces it the same way: Cycles and EEVEE draw it, the
  viewport too.

The material also holds the normal map, ready beside the surface shader.
"""
from __future__ import annotations

import json

import bpy
import numpy as np

from ..core.maps import Atlas, Maps, texel_faces, unit_directions
from ..core.micro.micromesh import MicroMesh
from . import bl_mesh
from .images import image

GROUP = "MicroMesh Height Map"
MODIFIER = "MicroMesh Height"
DIRECTION = "micromesh_unit_direction"
BASE_VERTEX = "micromesh_base_vertex"       # the base vertex each (seam-split) vertex copies
NOTES = "micromesh_maps"                    # how the height map was made (JSON)
ADAPTIVE = bpy.app.version >= (5, 0, 0)     # adaptive subdivision out of Experimental


def maps_object(context, source, mm: MicroMesh, maps: Maps, name: str) -> bpy.types.Object:
    """``name``: the base split at the atlas' seams, with UVs, unit directions, the height
    modifier and a material holding the normal map (and, on 5.0, the displacement)."""
    at = maps.atlas
    mesh, origin = bl_mesh.placed_mesh(name, mm.base.vertices[at.vertex], at.faces)
    uv = mesh.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", at.corner_uv.reshape(-1).astype(np.float32))
    a = mesh.attributes.new(DIRECTION, "FLOAT_VECTOR", "POINT")
    a.data.foreach_set("vector", unit_directions(mm)[at.vertex].astype(np.float32).reshape(-1))
    mesh.attributes.new(BASE_VERTEX, "INT", "POINT").data.foreach_set(
        "value", at.vertex.astype(np.int32))
    mesh[NOTES] = json.dumps(maps.notes)
    mesh.shade_smooth()
    obj, reused = bl_mesh.object_with_mesh(context, name, mesh, source,
                                           reuse=lambda o: o.modifiers.get(MODIFIER) is not None)
    if reused or origin is not None:   # world space, centred where far from the origin
        bl_mesh.place(obj, origin)
    height = image(f"{name}_height", maps.height)
    normal = image(f"{name}_normal", maps.normal)
    level = int(maps.notes.get("level", mm.levels.max(initial=0)))
    old = obj.modifiers.get(MODIFIER)
    if old is not None:
        obj.modifiers.remove(old)
    if ADAPTIVE:
        mod = obj.modifiers.new(MODIFIER, "SUBSURF")
        mod.subdivision_type = "SIMPLE"
        mod.levels, mod.render_levels = 1, level
        mod.use_adaptive_subdivision = True
        mod.adaptive_space, mod.adaptive_pixel_size = "PIXEL", 1.0
    else:
        mod = obj.modifiers.new(MODIFIER, "NODES")
        mod.node_group = _group(f"{GROUP} {name}", height)
        mod[_input(mod.node_group, "Level")] = level
    obj.data.materials.clear()
    obj.data.materials.append(_material(f"{name}_material", normal, height if ADAPTIVE else None))
    return obj


def maps_of(obj: bpy.types.Object | None) -> Maps | None:
    """The maps a maps object holds (its UVs and split vertices as the atlas, its height and
    normal images), for the files; None where ``obj`` is not one."""
    if obj is None or obj.type != "MESH" or BASE_VERTEX not in obj.data.attributes:
        return None
    mesh = obj.data
    mat = mesh.materials[0] if len(mesh.materials) else None
    name = obj.name
    height, normal = (bpy.data.images.get(f"{name}_{k}") for k in ("height", "normal"))
    if mat is None or height is None or normal is None:
        return None
    _, faces = bl_mesh.mesh_arrays(mesh)
    vertex = np.empty(len(mesh.vertices), np.int32)
    mesh.attributes[BASE_VERTEX].data.foreach_get("value", vertex)
    uv = np.zeros((len(mesh.vertices), 2))
    uv[faces.reshape(-1)] = bl_mesh.corner_uvs(mesh).reshape(-1, 2)
    atlas = Atlas(uv, faces.astype(np.int64), vertex.astype(np.int64))
    w, h = height.size
    pixels = np.empty(w * h * 4, np.float32)
    height.pixels.foreach_get(pixels)
    heights = pixels.reshape(h, w, 4)[..., 0].copy()
    normal.pixels.foreach_get(pixels)
    normals = pixels.reshape(h, w, 4)[..., :3].copy()
    return Maps(atlas, heights, normals, texel_faces(atlas, w, h)[0] >= 0,
                json.loads(mesh.get(NOTES, "{}")))


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
    lv.default_value, lv.min_value, lv.max_value = 4, 0, 6
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
    d.data_type, d.inputs["Name"].default_value = "FLOAT_VECTOR", DIRECTION
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


def _material(name: str, normal: bpy.types.Image,
              height: bpy.types.Image | None = None) -> bpy.types.Material:
    """Principled BSDF and the normal map ready beside it (connect it to the BSDF's Normal for
    low subdivision levels or for an engine: on the subdivided surface the geometry already
    carries the detail, and the map would tilt it twice); with ``height`` (5.0), the
    displacement: the height at the UVs along the normalised direction attribute, in world
    units, Cycles' Displacement only."""
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):      # 5.0: materials always have nodes
        mat.use_nodes = True
    nt = mat.node_tree
    nodes = nt.nodes
    for node in [x for x in nodes if x.type in ("TEX_IMAGE", "NORMAL_MAP", "UVMAP", "ATTRIBUTE",
                                                "VECT_MATH", "DISPLACEMENT", "SEPARATE_COLOR")]:
        nodes.remove(node)
    tex = nodes.new("ShaderNodeTexImage")
    tex.image, tex.label = normal, "Micro-mesh normal map"
    nmap = nodes.new("ShaderNodeNormalMap")
    nmap.uv_map = "UVMap"
    nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    if height is not None:
        mat.displacement_method = "DISPLACEMENT"
        out = next(x for x in nodes if x.type == "OUTPUT_MATERIAL")
        uv = nodes.new("ShaderNodeUVMap")
        uv.uv_map = "UVMap"
        h = nodes.new("ShaderNodeTexImage")
        h.image, h.label = height, "Height map"
        h.interpolation, h.extension = "Linear", "EXTEND"
        red = nodes.new("ShaderNodeSeparateColor")      # the value itself, not a luminance
        direction = nodes.new("ShaderNodeAttribute")
        direction.attribute_name = DIRECTION
        unit = nodes.new("ShaderNodeVectorMath")
        unit.operation = "NORMALIZE"
        disp = nodes.new("ShaderNodeDisplacement")
        disp.space = "OBJECT"
        disp.inputs["Midlevel"].default_value = 0.0
        disp.inputs["Scale"].default_value = 1.0
        nt.links.new(uv.outputs["UV"], h.inputs["Vector"])
        nt.links.new(h.outputs["Color"], red.inputs["Color"])
        nt.links.new(red.outputs[0], disp.inputs["Height"])
        nt.links.new(direction.outputs["Vector"], unit.inputs[0])
        nt.links.new(unit.outputs["Vector"], disp.inputs["Normal"])
        nt.links.new(disp.outputs["Displacement"], out.inputs["Displacement"])
    return mat
