"""The source object of a headless run (``batch.py``): the procedural demo, or one mesh
object imported from a file into the (empty) scene."""
from __future__ import annotations

from pathlib import Path

import bpy

from ..core.io import inputs
from ..core.io.gltf import GltfError
from ..core.io.micromesh_import import MicromeshFileError
from ..core.mesh.float32_origin import as_stored
from ..core.mesh.trimesh import TriMesh
from . import bl_mesh, importer_output


FILE_FRAME = "micromesh_file_frame"   # set on sources whose coordinates are the file's own


class SourceError(ValueError):
    """A file that holds no usable mesh; the message says why, in one line."""


def export_y_up(source) -> bool:
    """Whether an export of ``source``'s result turns Blender's Z-up into glTF's Y-up: not for
    sources read with their file's own coordinates (PLY, OBJ, STL, micro-mesh glTF), so results
    line up with the input file; yes for everything in Blender's frame (the demo, ``.blend``,
    and what Blender's importers turned Z-up), as Blender's own glTF exporter does."""
    return not bool(source.get(FILE_FRAME, False))


def demo_source(name: str = "demo_rock", subdivisions: int = 7):
    """A detailed procedural mesh: an icosphere displaced by two procedural textures."""
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=subdivisions, radius=1.0)
    obj = bpy.context.active_object
    obj.name = name
    for tex_type, size, strength in (("CLOUDS", 0.6, 0.35), ("VORONOI", 0.25, 0.08)):
        tex = bpy.data.textures.new(f"{name}_{tex_type.lower()}", tex_type)
        tex.noise_scale = size
        mod = obj.modifiers.new(tex_type.title(), "DISPLACE")
        mod.texture, mod.strength, mod.mid_level = tex, strength, 0.5
    _apply_modifiers(obj)
    return obj


def _apply_modifiers(obj) -> None:
    dg = bpy.context.evaluated_depsgraph_get()
    mesh = bpy.data.meshes.new_from_object(obj.evaluated_get(dg))
    old = obj.data
    obj.modifiers.clear()
    obj.data = mesh
    mesh.name = obj.name
    if old.users == 0:
        bpy.data.meshes.remove(old)


def import_source(path: Path, verbose: bool = False):
    """Import ``path`` into the (empty) scene; returns (one mesh object named after the file,
    its mesh as the construction takes it where we read the file ourselves, else None: the
    object's arrays are read back from Blender).

    The input formats' table (``core.io.inputs``) says who reads it. PLY, OBJ and STL go
    through our own readers, which refuse NaN or infinite coordinates, face indices out of
    range and files cut short: Blender's importers
    "repair" those silently (NaN becomes 0, faces are dropped); coordinates stay as in the
    file (no axis conversion), so results line up with the input file. A micro-mesh glTF (one
    with ``NV_displacement_micromap``) is read by ``core.io`` and its tessellation is the
    source. Such a mesh far from the origin is stored relative to a point near its centre,
    the object's location (``bl_mesh.placed_mesh``): Blender's float32 coordinates keep its
    detail and ``bl_mesh.mesh_to_arrays`` adds the two in float64. The other formats use
    Blender's importers (a glTF checked first by ``core.io.gltf_check``, which names what is
    wrong where the importer would fail or turn infinite positions into zeros); what they
    print stays off the terminal unless ``verbose``, and a failure is said in one line."""
    fmt = inputs.format_of(path)
    if fmt is None:
        raise SourceError(f"unsupported file type '{path.suffix}'")
    try:                    # MeshFileError (a ValueError) names the problem in a file of ours
        mesh = fmt.read(path) if fmt.read is not None else None
    except (MicromeshFileError, GltfError) as e:
        raise SourceError(str(e)) from None
    if mesh is not None:
        data, origin = bl_mesh.placed_mesh(path.stem, mesh.vertices, mesh.faces)
        obj = bpy.data.objects.new(path.stem, data)
        bpy.context.scene.collection.objects.link(obj)
        bl_mesh.place(obj, origin)
        obj[FILE_FRAME] = True
        return obj, TriMesh(as_stored(mesh.vertices), mesh.faces)
    before = set(bpy.data.objects)
    try:
        with importer_output.quiet(show=verbose):
            _IMPORTERS[fmt.importer](path)
        if fmt.importer == "blend":
            before = set()
    except RuntimeError as e:
        raise SourceError(f"cannot read: {importer_output.failure(e)}") from None
    meshes = [o for o in bpy.data.objects if o.type == "MESH" and o not in before
              and not o.get("micromesh_data") and o.micromesh_source is None]
    meshes = [o for o in meshes if len(o.data.polygons)]
    if not meshes:
        raise SourceError(f"no mesh with faces in {path.name}")
    obj = max(meshes, key=lambda o: len(o.data.polygons))
    if len(meshes) > 1 and fmt.importer != "blend":
        with bpy.context.temp_override(active_object=obj, selected_editable_objects=meshes):
            bpy.ops.object.join()
    obj.name = path.stem
    return obj, None


def _gltf(path: Path) -> None:
    _enable("io_scene_gltf2")
    bpy.ops.import_scene.gltf(filepath=str(path))


def _fbx(path: Path) -> None:
    _enable("io_scene_fbx")
    bpy.ops.import_scene.fbx(filepath=str(path))


# Blender's importers, by the name the input formats' table gives (``core.io.inputs``)
_IMPORTERS = {"gltf": _gltf, "fbx": _fbx,
              "usd": lambda path: bpy.ops.wm.usd_import(filepath=str(path)),
              "blend": lambda path: bpy.ops.wm.open_mainfile(filepath=str(path))}


def _enable(module: str) -> None:
    import addon_utils

    if module not in bpy.context.preferences.addons:
        addon_utils.enable(module, default_set=True)
