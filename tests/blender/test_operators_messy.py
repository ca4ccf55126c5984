"""Messy meshes through the panel's Construct, in the bpy wheel: a triangle soup (every face
with vertices of its own, as STL and many exports have it) with degenerate faces, a scan with
non-manifold fins and holes, and an object far from the origin. Each constructs like the clean
mesh would, crack-free, and the source is never changed."""
from __future__ import annotations

import pytest

bpy = pytest.importorskip("bpy")
import micromesh_path  # noqa: E402

micromesh_path.ensure_package()
from micromesh.core.mesh.trimesh import TriMesh  # noqa: E402
from micromesh.core.mesh.primitives import finned_sphere, noisy_sphere  # noqa: E402
from micromesh.operators import bl_mesh, writeback  # noqa: E402
from corpus import soup, with_degenerate  # noqa: E402
from test_operators_inputs import TINY  # noqa: E402

pytestmark = [pytest.mark.usefixtures("registered_addon"), pytest.mark.slow]   # constructions


def _source(name: str, mesh: TriMesh, location=(0.0, 0.0, 0.0)):
    """A new scene whose only object ``name`` holds ``mesh``, set as the panel's source."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    obj = bpy.data.objects.new(name, bl_mesh.arrays_to_mesh(name, mesh.vertices, mesh.faces))
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    s = bpy.context.scene.micromesh
    s.source, s.base = obj, None
    s.decimate_mode, s.ratio, s.base_max_error = "RATIO", 1 / 8, 0.0
    s.budget_mode, s.budget_value = "RATIO", 1.0
    s.camera_count, s.overrides = 4, TINY
    return obj


def _construct(obj) -> dict:
    before = len(obj.data.vertices), len(obj.data.polygons)
    assert bpy.ops.micromesh.construct(method="OPTIMIZE") == {"FINISHED"}
    assert (len(obj.data.vertices), len(obj.data.polygons)) == before      # source unchanged
    return writeback.load_outcome(bpy.data.objects[f"{obj.name}_micromesh"]).metrics


def test_a_soup_with_degenerate_faces_builds_on_the_welded_mesh():
    clean = TriMesh(*noisy_sphere(1280))
    m_clean = _construct(_source("clean", clean))
    m = _construct(_source("soup", with_degenerate(soup(clean))))
    assert m["base_faces"] == m_clean["base_faces"] and m["cracks"] == 0
    welded = [w for w in m["warnings"] if "coincident vertices" in w]
    assert len(welded) == 1 and int(welded[0].split()[0]) >= 3 * clean.n_faces - clean.n_vertices
    assert any("of no area" in w for w in m["warnings"])


def test_non_manifold_fins_and_holes_construct_crack_free():
    m = _construct(_source("fins", TriMesh(*finned_sphere(2000, fins=20, holes=30))))
    assert m["cracks"] == 0 and m["micro_triangles"] > m["base_faces"]
    assert any("20 non-manifold edges" in w for w in m["warnings"])


def test_an_object_far_from_the_origin_builds_the_same_base():
    mesh = TriMesh(*noisy_sphere(1280))
    near = _construct(_source("near", mesh))
    far = _construct(_source("far", mesh, location=(1e6, -1e6, 1e6)))
    assert far["base_faces"] == near["base_faces"] and far["cracks"] == 0
    assert abs(far["psnr"] - near["psnr"]) < 0.5
