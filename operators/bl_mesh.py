"""Blender mesh <-> array glue: evaluated meshes to ``TriMesh``, arrays to meshes, decimation.

Pure bpy helpers (no operators). Everything here is vectorised through ``foreach_get`` /
``foreach_set``; decimation uses Blender's own Decimate modifier (collapse) on a temporary
object that is removed again, so the caller's scene is left as it was.
"""
from __future__ import annotations

import bpy
import numpy as np

from ..core.mesh import MeshError, TriMesh


def mesh_arrays(mesh: bpy.types.Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Local-space vertices (n, 3) and loop triangles (m, 3) of a mesh datablock."""
    mesh.calc_loop_triangles()
    v = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", v)
    f = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", f)
    return v.reshape(-1, 3).astype(np.float64), f.reshape(-1, 3).astype(np.int64)


def mesh_to_arrays(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph | None = None,
                   world: bool = True, notes: list[str] | None = None) -> TriMesh:
    """The evaluated mesh of ``obj`` (modifiers applied), triangulated, optionally in world space.

    ``notes``: where to say, in words, that quads and n-gons were triangulated and that shape
    keys were mixed in.
    Raises :class:`~core.mesh.MeshError` when the object has no triangles.
    """
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    obj_eval = obj.evaluated_get(depsgraph)
    mesh = obj_eval.to_mesh()
    try:
        if mesh is None:
            raise MeshError(f"object '{obj.name}' has no mesh geometry")
        v, f = mesh_arrays(mesh)
        if notes is not None:
            sides = np.empty(len(mesh.polygons), dtype=np.int32)
            mesh.polygons.foreach_get("loop_total", sides)
            if (sides > 3).any():
                notes.append(f"{int((sides == 4).sum())} quads and {int((sides > 4).sum())} "
                             f"n-gons of '{obj.name}' were split into triangles "
                             f"({len(f)} in all)")
    finally:
        obj_eval.to_mesh_clear()
    if len(f) == 0:
        raise MeshError(f"object '{obj.name}' has no faces")
    keys = getattr(obj.data, "shape_keys", None)
    if notes is not None and keys is not None and len(keys.key_blocks) > 1:
        notes.append(f"'{obj.name}' has {len(keys.key_blocks) - 1} shape keys: their current "
                     "mix (as the viewport shows it) was used")
    if world:
        m = np.array(obj_eval.matrix_world, dtype=np.float64)
        v = v @ m[:3, :3].T + m[:3, 3]
    return TriMesh(v, f)


def mesh_uvs(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph | None = None
             ) -> np.ndarray | None:
    """(m, 3, 2) the active UV map at the corners of the evaluated mesh's triangles, in the
    order of :func:`mesh_to_arrays`; None where the mesh has no UV map."""
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    obj_eval = obj.evaluated_get(depsgraph)
    mesh = obj_eval.to_mesh()
    try:
        return corner_uvs(mesh) if mesh is not None else None
    finally:
        obj_eval.to_mesh_clear()


def corner_uvs(mesh: bpy.types.Mesh) -> np.ndarray | None:
    """(m, 3, 2) the active UV map at the corners of ``mesh``'s loop triangles; None where it
    has no UV map."""
    if mesh.uv_layers.active is None:
        return None
    mesh.calc_loop_triangles()
    loops = np.empty(3 * len(mesh.loop_triangles), dtype=np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    uv = np.empty(2 * len(mesh.loops), dtype=np.float32)
    mesh.uv_layers.active.data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)[loops].reshape(-1, 3, 2).astype(np.float64)


def arrays_to_mesh(name: str, vertices: np.ndarray, faces: np.ndarray) -> bpy.types.Mesh:
    """A new mesh datablock with the given triangles (edges computed, validated)."""
    v = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3)
    f = np.ascontiguousarray(faces, dtype=np.int32).reshape(-1, 3)
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(v))
    mesh.vertices.foreach_set("co", v.reshape(-1))
    mesh.loops.add(3 * len(f))
    mesh.loops.foreach_set("vertex_index", f.reshape(-1))
    mesh.polygons.add(len(f))
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * len(f), 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    return mesh


def decimate_object(obj: bpy.types.Object, target_faces: int | None = None,
                    ratio: float | None = None, symmetry: str | None = None,
                    vertex_group: str = "", vertex_group_factor: float = 1.0,
                    invert_vertex_group: bool = False, world: bool = True) -> TriMesh:
    """Decimate the evaluated mesh of ``obj`` with Blender's Decimate modifier (collapse).

    Works on a temporary copy (the evaluated mesh with all its layers, so vertex groups can
    weight the collapse); ``obj`` is never modified and everything created is removed again.
    ``symmetry`` is None or an axis 'X' / 'Y' / 'Z'. Returns a triangulated ``TriMesh``.
    """
    return decimate_object_uvs(obj, target_faces, ratio, symmetry, vertex_group,
                               vertex_group_factor, invert_vertex_group, world)[0]


def decimate_object_uvs(obj: bpy.types.Object, target_faces: int | None = None,
                        ratio: float | None = None, symmetry: str | None = None,
                        vertex_group: str = "", vertex_group_factor: float = 1.0,
                        invert_vertex_group: bool = False, world: bool = True
                        ) -> tuple[TriMesh, np.ndarray | None]:
    """:func:`decimate_object` and the active UV map it carried through the collapse, (m, 3,
    2) at the triangles' corners (None where ``obj`` has none): the base inherits the
    source's UVs and seams."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    obj_eval = obj.evaluated_get(depsgraph)
    temp_mesh = bpy.data.meshes.new_from_object(obj_eval, preserve_all_data_layers=True,
                                                depsgraph=depsgraph)
    temp = bpy.data.objects.new("_micromesh_decimate", temp_mesh)
    if world:
        temp.matrix_world = obj.matrix_world.copy()
    for name in (vg.name for vg in obj.vertex_groups):
        if name not in temp.vertex_groups:
            temp.vertex_groups.new(name=name)
    try:
        return _decimate_temp(temp, target_faces, ratio, symmetry, vertex_group,
                              vertex_group_factor, invert_vertex_group, world)
    finally:
        bpy.data.objects.remove(temp)
        bpy.data.meshes.remove(temp_mesh)


def decimate(vertices: np.ndarray, faces: np.ndarray, target_faces: int | None = None,
             ratio: float | None = None, symmetry: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Decimate a triangle mesh with Blender's Decimate modifier (collapse), in this bpy session.

    Give ``target_faces`` (triangles wanted) or ``ratio`` (0..1]; ``symmetry`` None or
    'X' / 'Y' / 'Z'. Returns triangulated (V (k, 3) float64, F (l, 3) int64); the temporary
    object and mesh are removed.
    """
    mesh = arrays_to_mesh("_micromesh_decimate", vertices, faces)
    temp = bpy.data.objects.new("_micromesh_decimate", mesh)
    try:
        out, _ = _decimate_temp(temp, target_faces, ratio, symmetry, "", 1.0, False, False)
    finally:
        bpy.data.objects.remove(temp)
        bpy.data.meshes.remove(mesh)
    return out.vertices, out.faces


def _decimate_temp(temp, target_faces, ratio, symmetry, vertex_group, vertex_group_factor,
                   invert_vertex_group, world) -> tuple[TriMesh, np.ndarray | None]:
    sizes = np.empty(len(temp.data.polygons), np.int32)
    temp.data.polygons.foreach_get("loop_total", sizes)
    n_tris = int((sizes - 2).sum())
    if n_tris == 0:
        raise MeshError("mesh to decimate has no faces")
    if target_faces is not None:
        if target_faces < 4:
            raise ValueError(f"target_faces must be at least 4, got {target_faces}")
        ratio = min(1.0, target_faces / n_tris)
    elif ratio is None:
        raise ValueError("give target_faces or ratio")
    if not (0.0 < ratio <= 1.0):
        raise ValueError(f"decimation ratio must be in (0, 1], got {ratio}")
    if symmetry not in (None, "", "X", "Y", "Z"):
        raise ValueError(f"symmetry must be None, 'X', 'Y' or 'Z', got {symmetry!r}")
    scene = bpy.context.scene
    scene.collection.objects.link(temp)
    try:
        mod = temp.modifiers.new("Decimate", "DECIMATE")
        mod.decimate_type = "COLLAPSE"
        mod.ratio = ratio
        mod.use_collapse_triangulate = True
        if symmetry:
            mod.use_symmetry = True
            mod.symmetry_axis = symmetry
        if vertex_group:
            if vertex_group not in temp.vertex_groups:
                raise ValueError(f"vertex group '{vertex_group}' not found")
            mod.vertex_group = vertex_group
            mod.vertex_group_factor = vertex_group_factor
            mod.invert_vertex_group = invert_vertex_group
        depsgraph = bpy.context.evaluated_depsgraph_get()
        depsgraph.update()
        return mesh_to_arrays(temp, depsgraph, world=world), mesh_uvs(temp, depsgraph)
    finally:
        scene.collection.objects.unlink(temp)


def object_with_mesh(context, name: str, mesh: bpy.types.Mesh, source: bpy.types.Object,
                     reuse) -> tuple[bpy.types.Object, bool]:
    """The object ``name`` holding ``mesh``; returns (object, reused).

    An existing object of that name for which ``reuse(obj)`` is true gets the new mesh (its old
    mesh is freed when nothing else uses it); otherwise a new object is linked into the
    source's first collection (the scene's collection if it has none or there is no source).
    """
    old = bpy.data.objects.get(name)
    if old is not None and reuse(old):
        old_mesh, old.data = old.data, mesh
        if old_mesh.users == 0:
            bpy.data.meshes.remove(old_mesh)
        return old, True
    obj = bpy.data.objects.new(name, mesh)
    coll = (source.users_collection[0] if source is not None and source.users_collection
            else context.scene.collection)
    coll.objects.link(obj)
    return obj, False
