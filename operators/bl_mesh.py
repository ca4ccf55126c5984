"""Blender mesh <-> array glue: evaluated meshes to ``TriMesh``, arrays to meshes, decimation.

Pure bpy helpers (no operators). Everything here is vectorised through ``foreach_get`` /
``foreach_set``; decimation uses Blender's own Decimate modifier (collapse) on a temporary
object that is removed again, so the caller's scene is left as it was.
"""
from __future__ import annotations

import bpy
import numpy as np
from mathutils import Matrix

from ..core.mesh.float32_origin import relative
from ..core.mesh.trimesh import MeshError, TriMesh


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
    Raises :class:`~core.mesh.MeshError` when the object has no triangles, or NaN or
    infinite coordinates (how many vertices).
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
    if world:      # in float64: a location far from the origin keeps the mesh's own detail
        m = np.array(obj_eval.matrix_world, dtype=np.float64)
        with np.errstate(invalid="ignore", over="ignore"):     # non-finite: refused below
            v = v @ m[:3, :3].T + m[:3, 3]
    bad = int((~np.isfinite(v)).any(axis=1).sum())
    if bad:
        raise MeshError(f"object '{obj.name}': {bad} of {len(v)} vertices have NaN or "
                        "infinite coordinates")
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


def placed_mesh(name: str, vertices: np.ndarray, faces: np.ndarray
                ) -> tuple[bpy.types.Mesh, np.ndarray | None]:
    """:func:`arrays_to_mesh` of world-space ``vertices``, relative to their float32 origin
    where float32 coordinates would blur them (``core.mesh.float32_origin``); that origin (None:
    the world's), where :func:`place` puts the object holding the mesh."""
    local, origin = relative(vertices)
    return arrays_to_mesh(name, local, faces), origin


def place(obj: bpy.types.Object, origin: np.ndarray | None) -> None:
    """``obj`` at ``origin`` (None: the world's origin), not rotated, not scaled."""
    obj.matrix_world = Matrix.Translation([0.0, 0.0, 0.0] if origin is None
                                          else [float(x) for x in origin])


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
