"""The live displacement preview on a result object: a Geometry Nodes group that moves each
vertex by (Strength − 1) · direction · displacement, the modifier that applies it, and the
scene-wide strength the panel's slider sets."""
from __future__ import annotations

import bpy

PREVIEW_GROUP = "MicroMesh Displacement Preview"
PREVIEW_MODIFIER = "MicroMesh Preview"


def preview_group() -> bpy.types.NodeTree:
    """Geometry Nodes group: position += (Strength − 1) · direction · displacement."""
    ng = bpy.data.node_groups.get(PREVIEW_GROUP)
    if ng is not None:
        return ng
    ng = bpy.data.node_groups.new(PREVIEW_GROUP, "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    s = ng.interface.new_socket("Strength", in_out="INPUT", socket_type="NodeSocketFloat")
    s.default_value, s.min_value, s.max_value = 1.0, -10.0, 10.0
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n = ng.nodes
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    direction = n.new("GeometryNodeInputNamedAttribute")
    direction.data_type = "FLOAT_VECTOR"
    direction.inputs["Name"].default_value = "micromesh_direction"
    disp = n.new("GeometryNodeInputNamedAttribute")
    disp.data_type = "FLOAT"
    disp.inputs["Name"].default_value = "micromesh_displacement"
    minus = n.new("ShaderNodeMath")
    minus.operation = "SUBTRACT"
    minus.inputs[1].default_value = 1.0
    mul = n.new("ShaderNodeMath")
    mul.operation = "MULTIPLY"
    scale = n.new("ShaderNodeVectorMath")
    scale.operation = "SCALE"
    setpos = n.new("GeometryNodeSetPosition")
    link = ng.links.new
    link(gin.outputs["Strength"], minus.inputs[0])
    link(minus.outputs[0], mul.inputs[0])
    link(disp.outputs["Attribute"], mul.inputs[1])
    link(direction.outputs["Attribute"], scale.inputs[0])
    link(mul.outputs[0], scale.inputs["Scale"])
    link(gin.outputs["Geometry"], setpos.inputs["Geometry"])
    link(scale.outputs[0], setpos.inputs["Offset"])
    link(setpos.outputs["Geometry"], gout.inputs["Geometry"])
    return ng


def _strength_key(ng) -> str:
    for item in ng.interface.items_tree:
        if getattr(item, "in_out", "") == "INPUT" and item.name == "Strength":
            return item.identifier
    raise KeyError("Strength")


def add_preview_modifier(obj: bpy.types.Object, strength: float = 1.0) -> bpy.types.Modifier:
    mod = obj.modifiers.get(PREVIEW_MODIFIER) or obj.modifiers.new(PREVIEW_MODIFIER, "NODES")
    mod.node_group = preview_group()
    mod[_strength_key(mod.node_group)] = float(strength)
    return mod


def set_preview_strength(scene, strength: float) -> None:
    """Set the preview strength on every result object of the scene."""
    for obj in scene.objects:
        mod = obj.modifiers.get(PREVIEW_MODIFIER)
        if mod is not None and mod.node_group is not None:
            mod[_strength_key(mod.node_group)] = float(strength)
            obj.update_tag()
