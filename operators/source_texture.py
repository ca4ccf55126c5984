"""The source's textures for Bake Maps: the images that feed its material's Principled BSDF
(base colour, metallic, roughness, alpha, emission, and a tangent-space normal map through a
Normal Map node), read as arrays with the UVs of its triangles, and the carried textures
(``core.maps.transfer_textures``, ``transfer_normal_map``) made images in the maps object's
material, each linked to the input it fed, so the baked asset keeps its look."""
from __future__ import annotations

from dataclasses import dataclass, field

import bpy
import numpy as np

from ..core.mesh.trimesh import TriMesh
from . import bl_mesh
from .images import image

CARRIED = ("Base Color", "Metallic", "Roughness", "Alpha", "Emission Color")
"""The Principled BSDF inputs whose image textures are carried as they are."""

NORMAL = "Normal"
"""The input a tangent-space normal map feeds through a Normal Map node: carried into the
atlas' tangent frame (``core.maps.transfer_normal_map``)."""

CONSTANTS = ("Metallic", "Roughness", "Emission Strength")
"""Value inputs copied as they are where no texture feeds them (the emission's strength
scales a carried emission colour)."""

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Blender's weights when a colour output feeds a value input (scene-linear Rec. 709)."""


@dataclass(eq=False)
class SourceImage:
    """One textured input: ``socket`` (of the Principled BSDF), ``output`` (of the Image
    Texture node: "Color" or "Alpha"), the image's pixels (H, W, 4, row 0 at the bottom)."""
    socket: str
    output: str
    pixels: np.ndarray
    colorspace: str
    is_float: bool

    @property
    def slug(self) -> str:
        if self.socket == NORMAL:        # beside the maps' own "<name>_normal"
            return "sourcenormal"
        return self.socket.split()[0].lower() + ("color" if self.socket == "Base Color" else "")

    def values(self, carried: np.ndarray) -> np.ndarray:
        """The scalar the input sees from a carried (R, R, 4) copy of this image: (R, R)."""
        if self.output == "Alpha":
            return carried[..., 3]
        return carried[..., :3] @ LUMINANCE


@dataclass(eq=False)
class SourceTextures:
    """What the worker needs: the source surface (world space), its UVs per triangle corner,
    the textured inputs, and the values of :data:`CONSTANTS` in the source's material."""
    mesh: TriMesh
    uv: np.ndarray
    images: list[SourceImage]
    constants: dict = field(default_factory=dict)
    normal_strength: float = 1.0


def _principled_nodes(obj: bpy.types.Object):
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None or mat.node_tree is None:
            continue
        yield from (n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")


def _image_link(socket):
    """(image, output name) of the Image Texture node linked into ``socket``, or None."""
    for link in socket.links:
        src = link.from_node
        if src.type == "TEX_IMAGE" and src.image is not None and src.image.size[0] > 1:
            return src.image, link.from_socket.name
    return None


def normal_map_node(bsdf):
    """The tangent-space Normal Map node feeding ``bsdf``'s Normal from an image, or None."""
    for link in bsdf.inputs[NORMAL].links:
        node = link.from_node
        if node.type == "NORMAL_MAP" and node.space == "TANGENT" \
                and _image_link(node.inputs["Color"]) is not None:
            return node
    return None


def textured_inputs(obj: bpy.types.Object):
    """(the object's first Principled BSDF that an Image Texture node feeds, {input name:
    (image, output name)} for its inputs of :data:`CARRIED` so fed and :data:`NORMAL` where a
    tangent-space Normal Map node of an image feeds it), or (None, {})."""
    for bsdf in _principled_nodes(obj):
        out = {name: found for name in CARRIED
               if (found := _image_link(bsdf.inputs[name])) is not None}
        node = normal_map_node(bsdf)
        if node is not None:
            out[NORMAL] = _image_link(node.inputs["Color"])
        if out:
            return bsdf, out
    return None, {}


def read(obj: bpy.types.Object) -> SourceTextures | None:
    """The source's textured inputs and UVs, or None where it has either not."""
    bsdf, found = textured_inputs(obj)
    uv = bl_mesh.mesh_uvs(obj) if found else None
    if uv is None:
        return None
    images, read_once = [], {}          # one image may feed two inputs (colour and alpha)
    for socket, (img, output) in found.items():
        if img.name not in read_once:
            w, h = img.size
            pixels = np.empty(w * h * 4, dtype=np.float32)
            img.pixels.foreach_get(pixels)
            read_once[img.name] = pixels.reshape(h, w, 4)
        images.append(SourceImage(socket, output, read_once[img.name],
                                  img.colorspace_settings.name, bool(img.is_float)))
    constants = {k: float(bsdf.inputs[k].default_value) for k in CONSTANTS}
    node = normal_map_node(bsdf)
    strength = float(node.inputs["Strength"].default_value) if node is not None else 1.0
    return SourceTextures(bl_mesh.mesh_to_arrays(obj), uv, images, constants, strength)


def make_image(name: str, pixels: np.ndarray, like: SourceImage) -> bpy.types.Image:
    """An image of (H, W, 4) pixels in the source's colour space, packed into the ``.blend``
    (PNG, or OpenEXR for a float source)."""
    return image(name, np.clip(pixels, 0.0, None), colorspace=like.colorspace,
                 float_buffer=like.is_float)


def _bsdf(mat: bpy.types.Material):
    nodes = mat.node_tree.nodes
    bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
    return bsdf if bsdf is not None else nodes.new("ShaderNodeBsdfPrincipled")


def copy_constants(mat: bpy.types.Material, textures: SourceTextures) -> None:
    """The source's :data:`CONSTANTS` onto the material's Principled BSDF."""
    bsdf = _bsdf(mat)
    for name, value in textures.constants.items():
        bsdf.inputs[name].default_value = value


def link_input(mat: bpy.types.Material, image: bpy.types.Image, like: SourceImage,
               normal_strength: float = 1.0) -> None:
    """The image, through the maps' UVs, into the material's Principled BSDF input that the
    source's image fed, from the same output; a normal map through a tangent-space Normal Map
    node of the maps' UVs with the source's strength."""
    nodes, bsdf, link = mat.node_tree.nodes, _bsdf(mat), mat.node_tree.links.new
    tex = nodes.new("ShaderNodeTexImage")
    tex.image, tex.label = image, f"Source {like.socket.lower()} on the atlas"
    uv = nodes.new("ShaderNodeUVMap")
    uv.uv_map = "UVMap"
    link(uv.outputs["UV"], tex.inputs["Vector"])
    if like.socket != NORMAL:
        link(tex.outputs[like.output], bsdf.inputs[like.socket])
        return
    nmap = nodes.new("ShaderNodeNormalMap")
    nmap.space, nmap.uv_map, nmap.label = "TANGENT", "UVMap", "Source normal map"
    nmap.inputs["Strength"].default_value = normal_strength
    link(tex.outputs["Color"], nmap.inputs["Color"])
    link(nmap.outputs["Normal"], bsdf.inputs[NORMAL])


def carry_textures(obj, textures, carried: list) -> None:
    """The carried textures as images of the maps object's material, each linked to the input
    it fed in the source's; the source's constants copied."""
    mat = obj.data.materials[0]
    copy_constants(mat, textures)
    for like, pixels in zip(textures.images, carried):
        img = make_image(f"{obj.name}_{like.slug}", pixels, like)
        link_input(mat, img, like, textures.normal_strength)
