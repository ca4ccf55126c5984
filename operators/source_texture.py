"""The source's base-colour texture for Bake Maps: found in its material, read as an array
with the UVs of its triangles, and the carried texture (``core.maps.transfer_texture``) made
an image in the maps object's material, so the baked asset keeps its look."""
from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np

from ..core.mesh import TriMesh
from . import bl_mesh
from .images import image


@dataclass(eq=False)
class SourceTexture:
    """What the worker needs: the source surface (world space), its UVs per triangle corner,
    the image's pixels (H, W, 4, row 0 at the bottom) and how to write the result."""
    mesh: TriMesh
    uv: np.ndarray
    pixels: np.ndarray
    colorspace: str
    is_float: bool


def base_color_image(obj: bpy.types.Object) -> bpy.types.Image | None:
    """The image feeding a Principled BSDF's Base Color in the object's materials (directly
    from an Image Texture node), else None."""
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None or mat.node_tree is None:
            continue
        for node in mat.node_tree.nodes:
            if node.type != "BSDF_PRINCIPLED":
                continue
            for link in node.inputs["Base Color"].links:
                src = link.from_node
                if src.type == "TEX_IMAGE" and src.image is not None and src.image.size[0] > 1:
                    return src.image
    return None


def read(obj: bpy.types.Object) -> SourceTexture | None:
    """The source's base-colour texture and UVs, or None where it has either not."""
    img = base_color_image(obj)
    if img is None:
        return None
    uv = bl_mesh.mesh_uvs(obj)
    if uv is None:
        return None
    w, h = img.size
    pixels = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(pixels)
    return SourceTexture(bl_mesh.mesh_to_arrays(obj), uv, pixels.reshape(h, w, 4),
                         img.colorspace_settings.name, bool(img.is_float))


def make_image(name: str, pixels: np.ndarray, like: SourceTexture) -> bpy.types.Image:
    """An image of (H, W, 4) pixels in the source's colour space, packed into the ``.blend``
    (PNG, or OpenEXR for a float source)."""
    return image(name, np.clip(pixels, 0.0, None), colorspace=like.colorspace,
                 float_buffer=like.is_float)


def link_base_color(mat: bpy.types.Material, image: bpy.types.Image) -> None:
    """The image, through the maps' UVs, into the material's Principled BSDF Base Color."""
    nodes = mat.node_tree.nodes
    bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
    if bsdf is None:
        bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    tex = nodes.new("ShaderNodeTexImage")
    tex.image, tex.label = image, "Source texture on the atlas"
    uv = nodes.new("ShaderNodeUVMap")
    uv.uv_map = "UVMap"
    mat.node_tree.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
