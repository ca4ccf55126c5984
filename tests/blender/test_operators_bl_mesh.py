"""bpy glue: evaluated meshes to arrays, arrays to meshes, Decimate-modifier decimation."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
import micromesh_path  # noqa: E402

micromesh_path.ensure_package()
from micromesh.operators import bl_decimate, bl_mesh  # noqa: E402


@pytest.fixture(autouse=True)
def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield


def _sphere(location=(0.0, 0.0, 0.0)):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, location=location)
    return bpy.context.active_object


def test_mesh_to_arrays_world_and_modifiers():
    obj = _sphere(location=(1.0, 2.0, 3.0))
    local = bl_mesh.mesh_to_arrays(obj, world=False)
    world = bl_mesh.mesh_to_arrays(obj)
    assert local.n_faces == 32 * 14 * 2 + 2 * 32  # quads split in two, fan triangles kept
    np.testing.assert_allclose(world.vertices - local.vertices, np.tile([1.0, 2.0, 3.0], (local.n_vertices, 1)), atol=1e-6)
    obj.modifiers.new("sub", "SUBSURF").levels = 1
    sub = bl_mesh.mesh_to_arrays(obj)
    assert sub.n_faces == 2 * (4 * 32 * 14 + 3 * 2 * 32)  # every quad -> 4 quads, tri -> 3
    assert sub.is_closed_manifold


def test_arrays_roundtrip():
    obj = _sphere()
    m = bl_mesh.mesh_to_arrays(obj)
    me = bl_mesh.arrays_to_mesh("copy", m.vertices, m.faces)
    assert not me.validate()
    v, f = bl_mesh.mesh_arrays(me)
    np.testing.assert_allclose(v, m.vertices, atol=1e-6)
    np.testing.assert_array_equal(f, m.faces)


@pytest.mark.parametrize("kw", [dict(target_faces=100), dict(ratio=0.2), dict(ratio=0.2, symmetry="X")])
def test_decimate_arrays_cleans_up(kw):
    m = bl_mesh.mesh_to_arrays(_sphere())
    n_obj, n_mesh = len(bpy.data.objects), len(bpy.data.meshes)
    v, f = bl_decimate.decimate(m.vertices, m.faces, **kw)
    assert (len(bpy.data.objects), len(bpy.data.meshes)) == (n_obj, n_mesh)
    want = kw.get("target_faces") or kw["ratio"] * m.n_faces
    assert abs(len(f) - want) <= 0.1 * want
    assert f.shape[1] == 3 and f.max() < len(v)
    # The decimated surface stays close to the unit sphere.
    r = np.linalg.norm(v, axis=1)
    assert np.all(np.abs(r - 1.0) < 0.1)


def test_decimate_object_respects_world_and_leaves_source():
    obj = _sphere(location=(5.0, 0.0, 0.0))
    before = len(obj.data.polygons)
    base = bl_decimate.decimate_object(obj, target_faces=200)
    assert len(obj.data.polygons) == before and len(obj.modifiers) == 0
    assert abs(base.n_faces - 200) <= 20
    assert np.allclose(base.vertices.mean(0), [5.0, 0.0, 0.0], atol=0.1)


def test_decimate_bad_input():
    m = bl_mesh.mesh_to_arrays(_sphere())
    with pytest.raises(ValueError):
        bl_decimate.decimate(m.vertices, m.faces, ratio=1.5)
    with pytest.raises(ValueError):
        bl_decimate.decimate(m.vertices, m.faces)
    with pytest.raises(ValueError):
        bl_decimate.decimate(m.vertices, m.faces, ratio=0.5, symmetry="W")


def test_decimate_object_vertex_group_weighting():
    obj = _sphere()
    vg = obj.vertex_groups.new(name="keep")
    top = [v.index for v in obj.data.vertices if v.co.z > 0]
    vg.add(top, 1.0, "REPLACE")

    def halves(m):
        c = m.vertices[m.faces].mean(1)[:, 2]
        return int((c > 0).sum()), int((c < 0).sum())

    plain = halves(bl_decimate.decimate_object(obj, ratio=0.3))
    weighted = halves(bl_decimate.decimate_object(obj, ratio=0.3, vertex_group="keep"))
    inverted = halves(bl_decimate.decimate_object(obj, ratio=0.3, vertex_group="keep",
                                              invert_vertex_group=True))
    assert abs(plain[0] - plain[1]) <= 0.1 * sum(plain)           # symmetric without weights
    assert abs(weighted[0] - weighted[1]) > 0.2 * sum(weighted)   # the group shifts the detail
    assert (weighted[0] > weighted[1]) != (inverted[0] > inverted[1])
    with pytest.raises(ValueError, match="vertex group"):
        bl_decimate.decimate_object(obj, ratio=0.3, vertex_group="nope")


def test_triangulated_polygons_are_said():
    """Quads and n-gons are split into triangles, and ``notes`` says how many of each; a mesh
    of triangles only gets no note."""
    bpy.ops.mesh.primitive_cylinder_add(vertices=8)       # 8 quads, two octagons
    notes: list[str] = []
    tm = bl_mesh.mesh_to_arrays(bpy.context.active_object, notes=notes)
    assert tm.n_faces == 8 * 2 + 2 * 6
    assert notes == [f"8 quads and 2 n-gons of '{bpy.context.active_object.name}' were split "
                     "into triangles (28 in all)"]
    bpy.ops.object.modifier_add(type="TRIANGULATE")
    notes.clear()
    bl_mesh.mesh_to_arrays(bpy.context.active_object, notes=notes)
    assert notes == []                                    # the evaluated mesh is what counts
