"""Each operator end to end on a small procedural mesh in the bpy wheel (background mode)."""
from __future__ import annotations

import json

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
import micromesh_path  # noqa: E402

micromesh_path.ensure_package()
from micromesh.core.render.cameras import supplement_up  # noqa: E402
from micromesh.operators import bl_mesh, cameras_io, construct_op, construct_scene, job, preview, writeback  # noqa: E402


pytestmark = pytest.mark.usefixtures("registered_addon")


@pytest.fixture
def scene():
    """An empty scene with a detailed procedural source (displaced, moved, modifiers live)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=4, radius=1.0, location=(2.0, -1.0, 0.5))
    src = bpy.context.active_object
    src.name = "rock"
    tex = bpy.data.textures.new("noise", "CLOUDS")
    tex.noise_scale = 0.6
    mod = src.modifiers.new("disp", "DISPLACE")
    mod.texture, mod.strength = tex, 0.2
    s = bpy.context.scene.micromesh
    s.decimate_mode, s.base_max_error = "TARGET", 0.0
    s.target_faces, s.level, s.camera_count = 120, 2, 8
    return bpy.context.scene


def _make_base(scene):
    assert bpy.ops.micromesh.make_base() == {"FINISHED"}
    return scene.micromesh.source, scene.micromesh.base


def test_make_base(scene):
    src = bpy.context.active_object
    n_src = len(src.data.vertices)
    src_world = bl_mesh.mesh_to_arrays(src)
    src2, base = _make_base(scene)
    assert src2 == src and base.name == "rock_base" and base.micromesh_source == src
    assert len(src.data.vertices) == n_src and len(src.modifiers) == 1  # source untouched
    assert all(len(p.vertices) == 3 for p in base.data.polygons)
    assert abs(len(base.data.polygons) - 120) <= 12
    bw = bl_mesh.mesh_to_arrays(base)  # world space, follows the displaced, moved source
    assert np.allclose(bw.vertices.mean(0), src_world.vertices.mean(0), atol=0.15)
    assert bw.is_closed_manifold and bw.genus == 0
    # Blender's Decimate stays available: ratio mode and symmetry go through the modifier.
    s = scene.micromesh
    s.base_method, s.decimate_mode, s.ratio, s.symmetry = "BLENDER", "RATIO", 0.05, "X"
    assert bpy.ops.micromesh.make_base() == {"FINISHED"}
    assert s.base == base and abs(len(base.data.polygons) - 0.05 * src_world.n_faces) < 20


def test_check_base_reports_and_selects(scene):
    src, base = _make_base(scene)
    assert bpy.ops.micromesh.check_base() == {"FINISHED"}
    assert "0 flipped faces" in scene.micromesh.check_report
    assert "0 non-manifold edges" in scene.micromesh.check_report
    bpy.ops.object.mode_set(mode="OBJECT")
    # Flip one face by hand: it must be reported and selected.
    m = bl_mesh.mesh_arrays(base.data)[1]
    m[7] = m[7][::-1]
    v = bl_mesh.mesh_arrays(base.data)[0]
    old = base.data
    base.data = bl_mesh.arrays_to_mesh("flipped", v, m)
    bpy.data.meshes.remove(old)
    assert bpy.ops.micromesh.check_base() == {"FINISHED"}
    assert "1 flipped faces" in scene.micromesh.check_report
    assert base.mode == "EDIT"
    bpy.ops.object.mode_set(mode="OBJECT")
    sel = np.zeros(len(base.data.polygons), bool)
    base.data.polygons.foreach_get("select", sel)
    assert sel[7] and sel.sum() == 1


def test_place_cameras_replaces_and_follows_the_up_rule(scene):
    s = scene.micromesh
    assert bpy.ops.micromesh.place_cameras() == {"FINISHED"}
    s.camera_count = 5
    assert bpy.ops.micromesh.place_cameras() == {"FINISHED"}
    objs = cameras_io.camera_objects(s.camera_collection)
    assert len(objs) == 5 and len([o for o in bpy.data.objects if o.type == "CAMERA"]) == 5
    ref = bl_mesh.mesh_to_arrays(s.source)
    center, radius = cameras_io.bounding_sphere(ref)
    for o in objs:
        m = np.array(o.matrix_world)
        eye, fwd, up = m[:3, 3], -m[:3, 2], m[:3, 1]
        assert np.linalg.norm(eye - center) == pytest.approx(3.5 * radius, rel=1e-5)
        assert np.allclose(fwd, (center - eye) / np.linalg.norm(center - eye), atol=1e-5)
        assert np.allclose(up, supplement_up((eye - center)[None])[0], atol=1e-5)
    cams = cameras_io.collection_cameras(s.camera_collection, 64)
    clip = cams.mvp @ np.append(center, 1.0)
    assert np.allclose(clip[:, :2] / clip[:, 3:4], 0.0, atol=1e-6)  # centre in the middle


def _check_consistent(res, base):
    out = writeback.load_outcome(res)
    mm = out.micromesh
    tess = mm.tessellate()
    me = res.data
    v, f = bl_mesh.mesh_arrays(me)
    np.testing.assert_allclose(v, tess.vertices, atol=1e-5 * (1 + np.abs(tess.vertices).max()))
    np.testing.assert_array_equal(f, tess.triangles)
    np.testing.assert_array_equal(writeback.read_attr(me, "micromesh_base_face", dtype=np.int64),
                                  tess.triangle_face)
    np.testing.assert_array_equal(writeback.read_attr(me, "micromesh_level", dtype=np.int64),
                                  mm.levels[tess.triangle_face])
    np.testing.assert_allclose(writeback.read_attr(me, "micromesh_displacement"), mm.displacements,
                               rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(writeback.read_attr(me, "micromesh_direction", "vector", width=3),
                               mm.micro_vertex_directions(), atol=1e-6)
    bv, bf = bl_mesh.mesh_arrays(base.data)
    np.testing.assert_allclose(bv, mm.base.vertices, atol=1e-5)  # base gets the final positions
    np.testing.assert_array_equal(bf, mm.base.faces)
    np.testing.assert_array_equal(writeback.read_attr(base.data, "micromesh_level", dtype=np.int64),
                                  mm.levels)
    np.testing.assert_array_equal(writeback.read_attr(base.data, "micromesh_edge_flags", dtype=np.int64),
                                  mm.topology.flags)
    np.testing.assert_allclose(writeback.read_attr(base.data, "micromesh_direction", "vector", width=3),
                               mm.directions, atol=1e-6)
    return out


@pytest.mark.slow
def test_construct_projection_writes_consistent_attributes(scene):
    src, base = _make_base(scene)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    res = bpy.data.objects["rock_micromesh"]
    assert res.micromesh_source == src and res.micromesh_base == base
    out = _check_consistent(res, base)
    assert out.method == "projection" and set(out.micromesh.levels) == {2}
    m = json.loads(res["micromesh_metrics"])
    assert m["micro_triangles"] == 16 * len(base.data.polygons) and m["shell_volume"] > 0
    # Baked surface lies on the source: micro-vertices close to the reference.
    ref = bl_mesh.mesh_to_arrays(src)
    from micromesh.core.micro.metrics import distance_to_mesh

    d = distance_to_mesh(out.micromesh.micro_vertex_positions(), ref.vertices, ref.faces)
    assert np.median(d) < 1e-3 and np.percentile(d, 95) < 0.02
    assert res.modifiers[preview.PREVIEW_MODIFIER].node_group.name == preview.PREVIEW_GROUP
    assert res.data.color_attributes.active_color.name == "micromesh_level_color"


@pytest.mark.slow
def test_construct_optimizer_tiny_budget(scene):
    pytest.importorskip("micromesh.core.construct")
    s = scene.micromesh
    _make_base(scene)
    s.camera_count = 4
    assert bpy.ops.micromesh.place_cameras() == {"FINISHED"}
    s.overrides = ("iterations=6 subdivide_at=2,4 max_level=2 train_resolution=48 n_views=4 "
                   "views_per_iter=2 eval_views=2 eval_resolution=48 lod_resolution=48")
    assert bpy.ops.micromesh.construct(method="OPTIMIZE") == {"FINISHED"}
    res = bpy.data.objects["rock_micromesh"]
    out = _check_consistent(res, s.base)
    assert out.method == "optimize" and out.history
    assert out.settings["iterations"] == 6
    assert np.isfinite(json.loads(res["micromesh_metrics"])["psnr"])


@pytest.mark.slow
def test_construct_without_a_base_builds_one(scene):
    """Construct with no base object: the worker builds the base (core.base, the panel's
    targets) and the result comes with its base object, topology kept."""
    pytest.importorskip("micromesh.core.construct")
    s = scene.micromesh
    src = bpy.context.active_object
    s.source, s.base = src, None
    s.decimate_mode, s.ratio, s.budget_mode, s.budget_value = "RATIO", 1 / 16, "RATIO", 1.0
    s.overrides = ("iterations=6 subdivide_at=2,4 max_level=2 train_resolution=48 "
                   "views_per_iter=2 eval_views=2 eval_resolution=48 lod_resolution=48")
    assert "rock_base" not in bpy.data.objects
    assert bpy.ops.micromesh.construct(method="OPTIMIZE") == {"FINISHED"}
    base = bpy.data.objects["rock_base"]
    assert s.base == base and base.micromesh_source == src
    out = _check_consistent(bpy.data.objects["rock_micromesh"], base)
    m = out.metrics
    assert m["base"]["topology_base"] == m["base"]["topology_input"] and m["warnings"] == []
    assert m["micro_triangles"] <= bl_mesh.mesh_to_arrays(src).n_faces      # budget 1x


@pytest.mark.slow
def test_save_reload_and_preview_strength(scene, tmp_path):
    _make_base(scene)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    before = writeback.load_outcome(bpy.data.objects["rock_micromesh"])
    path = str(tmp_path / "saved.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert "rock_micromesh" not in bpy.data.objects
    bpy.ops.wm.open_mainfile(filepath=path)
    res = bpy.data.objects["rock_micromesh"]
    after = writeback.load_outcome(res)
    for k in ("directions", "levels", "displacements"):
        np.testing.assert_array_equal(getattr(after.micromesh, k), getattr(before.micromesh, k))
    np.testing.assert_array_equal(after.micromesh.base.vertices, before.micromesh.base.vertices)
    np.testing.assert_array_equal(after.bounds.scale, before.bounds.scale)
    assert after.metrics == json.loads(json.dumps(before.metrics))
    assert res.micromesh_base.name == "rock_base" and res.micromesh_source.name == "rock"
    # The Geometry Nodes preview: strength 0 shows the undisplaced micro-mesh.
    bpy.context.scene.micromesh.preview_strength = 0.0
    flat = bl_mesh.mesh_to_arrays(res)
    np.testing.assert_allclose(flat.vertices, after.micromesh.micro_vertex_base_positions(), atol=1e-4)
    bpy.context.scene.micromesh.preview_strength = 1.0
    full = bl_mesh.mesh_to_arrays(res)
    np.testing.assert_allclose(full.vertices, after.micromesh.micro_vertex_positions(), atol=1e-4)


@pytest.mark.slow
def test_construct_twice_keeps_the_stored_result(scene, tmp_path):
    """A second Construct on the same source replaces the stored micro-mesh whole (Blender
    cut a reassigned bytes property at its first zero byte), in the scene and after saving."""
    _make_base(scene)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    scene.micromesh.level = 1
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    res = bpy.data.objects["rock_micromesh"]
    assert set(writeback.load_outcome(res).micromesh.levels) == {1}
    path = str(tmp_path / "twice.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    again = writeback.load_outcome(bpy.data.objects["rock_micromesh"])
    assert set(again.micromesh.levels) == {1} and again.bounds is not None


@pytest.mark.slow
def test_undo_restores_the_scene(scene):
    src, base = _make_base(scene)
    base_before = bl_mesh.mesh_arrays(base.data)[0].copy()
    bpy.ops.ed.undo_push(message="before construct")
    names = set(bpy.data.objects.keys())
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    bpy.ops.ed.undo_push(message="after construct")
    assert "rock_micromesh" in bpy.data.objects
    bpy.ops.ed.undo()
    assert set(bpy.data.objects.keys()) == names
    base = bpy.data.objects["rock_base"]
    assert "micromesh_level" not in base.data.attributes
    np.testing.assert_array_equal(bl_mesh.mesh_arrays(base.data)[0], base_before)


def test_cancel_through_should_stop_leaves_no_new_objects(scene):
    _make_base(scene)
    names = set(bpy.data.objects.keys())
    n_meshes = len(bpy.data.meshes)
    prep = construct_scene.prepare(bpy.context, "projection")
    j = job.Job(prep.work)
    j.cancel()  # should_stop() is true from the first check
    j.start()
    t = 0
    while not j.poll().done and t < 500:
        j.join(0.02)
        t += 1
    assert j.state.cancelled and j.state.result is None
    construct_op.sync_state(bpy.context.scene, j.state)
    assert set(bpy.data.objects.keys()) == names and len(bpy.data.meshes) == n_meshes
    assert bpy.context.scene.micromesh.phase == j.state.phase


def test_modal_timer_tick_updates_the_panel_state(scene):
    state = job.JobState(phase="optimize", iteration=30, total=120, psnr=33.3, eta_s=12.0)
    state.fraction = 0.25
    construct_op.sync_state(bpy.context.scene, state)
    s = bpy.context.scene.micromesh
    assert (s.phase, s.iteration, s.progress) == ("optimize", 30, 0.25)
    assert s.psnr == pytest.approx(33.3) and "30/120" in s.status


@pytest.mark.slow
def test_face_level_override_kept(scene):
    src, base = _make_base(scene)
    bpy.context.view_layer.objects.active = base
    sel = np.zeros(len(base.data.polygons), bool)
    sel[:10] = True
    base.data.polygons.foreach_set("select", sel)
    s = scene.micromesh
    s.level = 1
    # A short optimiser run: "keep levels" refines the displacements by optimisation now.
    s.overrides = ("iterations=15 train_resolution=64 views_per_iter=2 eval_views=4 "
                   "eval_resolution=96 geom_error=false")
    base_before = bl_mesh.mesh_to_arrays(base).vertices
    assert bpy.ops.micromesh.set_face_level(level=3) == {"FINISHED"}
    assert s.keep_levels
    assert bpy.ops.micromesh.construct() == {"FINISHED"}
    out = writeback.load_outcome(bpy.data.objects["rock_micromesh"])
    mm = out.micromesh
    assert out.method == "optimize" and len(out.history["psnr"]) == 15
    assert any(e.get("fixed_levels") for e in out.history["events"])
    assert (mm.levels[:10] == 3).all()
    assert mm.levels.min() == 1 and set(np.unique(mm.levels)) <= {1, 2, 3}  # balanced ±1
    stored = writeback.read_attr(base.data, "micromesh_level", dtype=np.int64)
    np.testing.assert_array_equal(stored, mm.levels)
    np.testing.assert_allclose(bl_mesh.mesh_to_arrays(base).vertices, base_before, atol=1e-6)


@pytest.mark.slow
def test_report_image(scene):
    _make_base(scene)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    bpy.context.view_layer.objects.active = bpy.data.objects["rock_micromesh"]
    assert bpy.ops.micromesh.open_report() == {"FINISHED"}
    img = bpy.data.images["rock_micromesh_report"]
    from micromesh.core.report.figure import SIZE

    assert tuple(img.size) == SIZE
    res = bpy.data.objects["rock_micromesh"]
    report = json.loads(res["micromesh_report"])
    assert report["metrics"]["micro_triangles"] == writeback.load_outcome(res).metrics[
        "micro_triangles"]


def test_bad_input_is_reported(scene):
    s = scene.micromesh
    s.overrides = "no_such_setting=1"
    _make_base(scene)
    with pytest.raises(RuntimeError, match="unknown setting"):
        bpy.ops.micromesh.construct(method="PROJECTION")
    assert "rock_micromesh" not in bpy.data.objects


def test_closing_the_file_stops_a_running_construction(scene):
    import threading

    from micromesh.core.workflow import Cancelled

    running = threading.Event()

    def work(progress, should_stop):
        running.set()
        while not should_stop():
            running.wait(0.001)
        raise Cancelled()

    j = job.Job(work).start()
    running.wait(5)
    bpy.ops.wm.read_factory_settings(use_empty=True)  # load_pre handler stops the worker
    assert not j.alive and job.active_job() is None
    assert j.poll().cancelled


@pytest.mark.slow
def test_export_then_import_gives_the_same_micromesh(scene, tmp_path):
    """File ▸ Export ▸ Micro-Mesh writes the glTF set (Y-up); File ▸ Import ▸ Micro-Mesh reads
    it back (Z-up) into a base and a result with a construction's attributes."""
    _make_base(scene)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    res = bpy.data.objects["rock_micromesh"]
    before = writeback.load_outcome(res)
    bpy.context.view_layer.objects.active = scene.micromesh.source   # the source: its result
    path = tmp_path / "rock.gltf"
    assert bpy.ops.micromesh.export(filepath=str(path), values="float") == {"FINISHED"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rock.bary", "rock.bin", "rock.gltf"]
    glb = tmp_path / "one.glb"
    assert bpy.ops.micromesh.export(filepath=str(glb), container="GLB") == {"FINISHED"}
    assert glb.exists()
    assert bpy.ops.micromesh.import_file(filepath=str(path)) == {"FINISHED"}
    imp = bpy.data.objects["rock_micromesh.001"]   # the construction is not replaced
    assert imp is not res and bpy.context.active_object == imp
    after = writeback.load_outcome(imp)
    assert after.method == "import" and after.metrics["warnings"] == []
    np.testing.assert_array_equal(after.micromesh.levels, before.micromesh.levels)
    # per-vertex direction bounds cannot say every position exactly: the report's
    # quantisation error (1.1e-3 of the diagonal on this coarse base) bounds the difference
    diag = before.micromesh.base.bbox_diagonal
    np.testing.assert_allclose(after.micromesh.micro_vertex_positions(),
                               before.micromesh.micro_vertex_positions(), atol=1.5e-3 * diag)
    assert imp.micromesh_base.data.attributes.get("micromesh_level") is not None
    assert len(imp.data.polygons) == before.micromesh.topology.n_triangles
    bad = tmp_path / "bad.gltf"
    bad.write_text("{not json")
    with pytest.raises(RuntimeError, match="not valid glTF"):
        bpy.ops.micromesh.import_file(filepath=str(bad))


@pytest.mark.slow
def test_bake_maps_draws_the_source_through_blender_modifiers(scene):
    """Bake Maps makes <source>_maps: the base with UVs whose height modifier, evaluated by
    Blender, puts the surface on the source's (a tenth as far from it as the base it
    displaces)."""
    _make_base(scene)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    out = writeback.load_outcome(bpy.data.objects["rock_micromesh"])
    assert bpy.ops.micromesh.bake_maps(resolution=512) == {"FINISHED"}
    obj = bpy.data.objects["rock_maps"]
    assert obj.data.uv_layers.get("UVMap") is not None and obj.data.materials[0] is not None
    assert bpy.data.images["rock_maps_height"].packed_file is not None
    mod = obj.modifiers["MicroMesh Height"]
    ev = bl_mesh.mesh_to_arrays(obj)            # the modifier, evaluated
    mm = out.micromesh
    from micromesh.core.spatial.bake import nearest_points

    source = bl_mesh.mesh_to_arrays(bpy.data.objects["rock"])
    diag = source.bbox_diagonal
    if mod.type == "NODES":    # 4.2-4.5: Blender subdivides a triangle into 3 quads, then 4
        assert ev.n_faces == mm.base.n_faces * 3 * 4 ** 3 * 2   # each quad (level 4)
        _, _, d = nearest_points(ev.vertices, source)
        mod.show_viewport = False
        _, _, d0 = nearest_points(bl_mesh.mesh_to_arrays(obj).vertices, source)
        rms, rms0 = (np.sqrt((x ** 2).mean()) / diag for x in (d, d0))
        assert rms < 0.1 * rms0 and rms < 2e-3, (rms, rms0)
    else:                      # 5.0: Cycles subdivides and displaces at render time
        assert mod.type == "SUBSURF" and mod.use_adaptive_subdivision


@pytest.mark.slow
def test_export_writes_the_maps_bake_maps_fitted(scene, tmp_path):
    """File ▸ Export ▸ Micro-Mesh, format "Base + height map": the maps object's atlas and
    images as the maps' formats of core.io.formats (the glTF, the USD, the images), the same
    heights the maps object holds; refused, with the reason, before Bake Maps."""
    _make_base(scene)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    bpy.context.view_layer.objects.active = scene.micromesh.source
    with pytest.raises(RuntimeError, match="Bake Maps first"):
        bpy.ops.micromesh.export(filepath=str(tmp_path / "none.gltf"), container="MAPS")
    assert not list(tmp_path.iterdir())
    assert bpy.ops.micromesh.bake_maps(resolution=256) == {"FINISHED"}
    assert bpy.ops.micromesh.export(filepath=str(tmp_path / "rock.gltf"),
                                    container="MAPS") == {"FINISHED"}
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["rock_base.gltf", "rock_base.bin", "rock_height.png", "rock_height.exr",
         "rock_normal.png", "rock.usda"])
    from micromesh.core.io.gltf import Document
    from micromesh.operators.maps_object import maps_of

    maps = maps_of(bpy.data.objects["rock_maps"])
    assert maps.notes["level"] == 4 and max(maps.notes["seam_gap_max"].values()) < 1e-5
    doc = Document(tmp_path / "rock_base.gltf")
    ext = doc.doc["materials"][0]["extensions"]["KHR_materials_displacement"]
    lo, hi = float(maps.height.min()), float(maps.height.max())
    assert ext["displacementGeometryOffset"] == pytest.approx(lo)
    assert ext["displacementGeometryFactor"] == pytest.approx(hi - lo)


@pytest.mark.slow
def test_bake_maps_refuses_a_resolution_that_is_not_a_power_of_two(scene):
    _make_base(scene)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    with pytest.raises(RuntimeError, match="power of two"):
        bpy.ops.micromesh.bake_maps(resolution=1000)
    assert bpy.data.objects.get("rock_maps") is None          # nothing was made
