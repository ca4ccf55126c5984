"""Blender's Decimate modifier (collapse) on a temporary copy: the simplest alternative to
``core.base``'s builder, and an artist's option (symmetry, vertex-group weights); the source's
UV map comes through the collapse with the triangles."""
from __future__ import annotations

import bpy
import numpy as np

from ..core.base import builders
from ..core.mesh.trimesh import MeshError, TriMesh
from .bl_mesh import arrays_to_mesh, mesh_to_arrays, mesh_uvs


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


def decimate_base(source: bpy.types.Object, settings, reference_faces: int | None = None,
                  **options) -> tuple[TriMesh, np.ndarray | None]:
    """Blender's row of ``core.base.builders``: :func:`decimate_object_uvs` of ``source`` to
    the settings' target (``base_ratio``, ``base_faces`` of ``reference_faces`` triangles, at
    least 4) unless ``options`` give ``target_faces`` or ``ratio`` (then ``settings`` may be
    None); ``options``: the other arguments of :func:`decimate_object_uvs` (symmetry, vertex
    group)."""
    if "target_faces" not in options and "ratio" not in options:
        from ..core.base import target_faces

        n = reference_faces if reference_faces is not None else mesh_to_arrays(source).n_faces
        options["target_faces"] = max(4, min(target_faces(n, settings.base_ratio,
                                                          settings.base_faces), n))
    return decimate_object_uvs(source, **options)


builders.implement("blender", decimate_base)
