"""Sources and cameras as artists leave them, in the bpy wheel: shape keys, mesh data shared by
two objects, loose vertices, objects of 1e-6 and 1e6 units, an empty camera collection and
cameras inside the object. Each case gives a result or a clear word, and the source is never
changed."""
from __future__ import annotations


import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
import micromesh_path  # noqa: E402

micromesh_path.ensure_package()
from micromesh.core.construct.frame import unit_cameras  # noqa: E402
from micromesh.core.construct.views import view_coverage  # noqa: E402
from micromesh.core.mesh.normalization import unit_sphere_normalization  # noqa: E402
from micromesh.core.settings.fields import preset  # noqa: E402
from micromesh.operators import bl_mesh, cameras_io, writeback  # noqa: E402

TINY = ("iterations=4 subdivide_at=2 max_level=1 train_resolution=48 n_views=4 "
        "views_per_iter=2 eval_views=2 eval_resolution=48 lod_resolution=48")


pytestmark = pytest.mark.usefixtures("registered_addon")


@pytest.fixture
def scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=1.0, location=(1.0, 0.0, 0.0))
    src = bpy.context.active_object
    src.name = "rock"
    s = bpy.context.scene.micromesh
    s.source, s.base = src, None
    s.decimate_mode, s.ratio, s.base_max_error = "RATIO", 1 / 8, 0.0
    s.budget_mode, s.budget_value = "RATIO", 1.0
    s.camera_count, s.overrides = 4, TINY
    return bpy.context.scene


def _vertices(data) -> np.ndarray:
    """Coordinates of a mesh's vertices or of a shape key's points."""
    points = data.data if isinstance(data, bpy.types.ShapeKey) else data.vertices
    v = np.empty(3 * len(points), np.float32)
    points.foreach_get("co", v)
    return v.reshape(-1, 3)


def _construct(scene) -> dict:
    assert bpy.ops.micromesh.construct(method="OPTIMIZE") == {"FINISHED"}
    res = bpy.data.objects[f"{scene.micromesh.source.name}_micromesh"]
    return writeback.load_outcome(res).metrics


@pytest.mark.slow
def test_shape_keys_are_mixed_in_and_said(scene):
    src = scene.micromesh.source
    src.shape_key_add(name="Basis")
    key = src.shape_key_add(name="Wide")
    for p in key.data:
        p.co.x *= 2.0
    key.value = 1.0
    before = [_vertices(k) for k in src.data.shape_keys.key_blocks]
    m = _construct(scene)
    assert "'rock' has 1 shape keys: their current mix (as the viewport shows it) was used" \
        in m["warnings"]
    out = writeback.load_outcome(bpy.data.objects["rock_micromesh"]).micromesh
    x = out.tessellate().vertices[:, 0]
    assert x.max() - x.min() > 3.5                     # the wide mix, 4 units across
    after = [_vertices(k) for k in src.data.shape_keys.key_blocks]
    assert all(np.array_equal(a, b) for a, b in zip(before, after)) and key.value == 1.0


@pytest.mark.slow
def test_mesh_data_shared_by_two_objects(scene):
    """Construct on one of two objects that share their mesh: the result stands where that
    object is; the shared mesh and the other object are unchanged."""
    src = scene.micromesh.source
    twin = bpy.data.objects.new("twin", src.data)
    scene.collection.objects.link(twin)
    twin.location = (-5.0, 0.0, 0.0)
    assert src.data.users == 2
    before = _vertices(src.data)
    _construct(scene)
    out = writeback.load_outcome(bpy.data.objects["rock_micromesh"]).micromesh
    x = out.tessellate().vertices
    np.testing.assert_allclose((x.max(0) + x.min(0)) / 2, (1.0, 0.0, 0.0), atol=0.1)
    assert np.array_equal(_vertices(src.data), before) and twin.data == src.data
    assert tuple(twin.location) == (-5.0, 0.0, 0.0) and "twin_micromesh" not in bpy.data.objects


@pytest.mark.slow
def test_loose_vertices_and_edges_are_left_out(scene):
    """Loose vertices and an edge far away neither move the frame nor reach the result."""
    import bmesh

    src = scene.micromesh.source
    bm = bmesh.new()
    bm.from_mesh(src.data)
    a, b = bm.verts.new((50.0, 0.0, 0.0)), bm.verts.new((50.0, 9.0, 0.0))
    bm.edges.new((a, b))
    bm.verts.new((-40.0, 0.0, 0.0))
    bm.to_mesh(src.data)
    bm.free()
    m = _construct(scene)
    assert "3 vertices in no face (loose vertices or edges) were left out" in m["warnings"]
    out = writeback.load_outcome(bpy.data.objects["rock_micromesh"]).micromesh
    assert np.abs(out.tessellate().vertices - (1.0, 0.0, 0.0)).max() < 1.2
    assert m["psnr"] > 25


@pytest.mark.parametrize("size", [1e-6, 1e6])
def test_placed_cameras_see_objects_of_any_size(scene, size):
    """Place Cameras around an object of 1e-6 or 1e6 units: brought into the unit frame as
    a construction brings them, every camera sees the whole front of the object."""
    src = scene.micromesh.source
    src.data.transform(np.diag([size, size, size, 1.0]).tolist())
    src.location = (3 * size, 0.0, 0.0)
    scene.micromesh.camera_count = 6
    assert bpy.ops.micromesh.place_cameras() == {"FINISHED"}
    world = bl_mesh.mesh_to_arrays(src)
    norm = unit_sphere_normalization(world.vertices)
    cams = unit_cameras(cameras_io.collection_cameras(scene.micromesh.camera_collection, 64),
                        norm, preset("fast"), 64)
    unit = world.with_vertices(norm.apply(world.vertices))
    covered, back = view_coverage(unit, cams, "cpu")
    assert (covered > 0.15 * 96 * 96).all() and (back == 0).all(), (covered, back)


@pytest.mark.slow
def test_an_empty_camera_collection_is_said(scene):
    s = scene.micromesh
    s.camera_collection = bpy.data.collections.new("Empty Cameras")
    s.use_scene_cameras = True
    m = _construct(scene)
    assert ("the camera collection 'Empty Cameras' holds no cameras: 4 cameras around the "
            "object were used") in m["warnings"]


@pytest.mark.slow
def test_cameras_inside_the_object_are_said(scene):
    s = scene.micromesh
    assert bpy.ops.micromesh.place_cameras() == {"FINISHED"}
    for cam in cameras_io.camera_objects(s.camera_collection):   # into the middle, same aim
        cam.location = (1.0, 0.0, 0.0)
    s.use_scene_cameras = True
    m = _construct(scene)
    assert any(w.startswith("every camera that sees the object (4 of 4) sees only the back")
               for w in m["warnings"]), m["warnings"]
    assert np.isfinite(m["psnr"])                         # the result is there, and said


def test_the_panel_shows_the_estimate(scene):
    from micromesh.ui import panels

    text = panels._estimate_text(bpy.context)
    # 1x its 320 faces, a tenth over: the estimate's allowance for the count the base gives
    assert text.startswith("Estimate: about ") and "for 352 micro-triangles" in text
    scene.micromesh.overrides = "no_such_setting=1"
    assert panels._estimate_text(bpy.context) == ""


@pytest.mark.slow
def test_bake_maps_carries_the_source_texture_onto_the_atlas(scene):
    """A source with UVs, an image in its material's Base Color and another (non-colour
    data) in its Roughness, and a Metallic value: Bake Maps gives the maps object those
    textures on its own atlas, each linked to the input it fed, and the same Metallic; each
    texel holds the colour the source shows at the texel's point. For engines the roughness
    goes into glTF's metallic-roughness texture (green), the Metallic value beside it (blue)."""
    src = scene.micromesh.source
    me = src.data
    corner_vertex = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", corner_vertex)
    p = bl_mesh.mesh_arrays(me)[0][corner_vertex]
    p /= np.linalg.norm(p, axis=1, keepdims=True)            # a latitude/longitude projection
    uv = np.stack([0.5 + np.arctan2(p[:, 1], p[:, 0]) / (2 * np.pi),
                   0.5 + np.arcsin(np.clip(p[:, 2], -1, 1)) / np.pi], 1)
    me.uv_layers.new(name="UVMap").data.foreach_set("uv", uv.astype(np.float32).reshape(-1))
    w = h = 64
    img = bpy.data.images.new("paint", w, h)
    yy, xx = np.mgrid[0:h, 0:w]
    pixels = np.stack([(xx + 0.5) / w, (yy + 0.5) / h, np.full((h, w), 0.25),
                       np.ones((h, w))], -1).astype(np.float32)
    img.pixels.foreach_set(pixels.reshape(-1))
    mat = bpy.data.materials.new("painted")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    rough = bpy.data.images.new("rough", w, h)
    rough.colorspace_settings.name = "Non-Color"
    rough.pixels.foreach_set(np.repeat(pixels[..., 1:2], 4, -1).reshape(-1))   # grey: v
    rtex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    rtex.image = rough
    mat.node_tree.links.new(rtex.outputs["Color"], bsdf.inputs["Roughness"])
    bsdf.inputs["Metallic"].default_value = 0.7
    src.data.materials.append(mat)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    assert bpy.ops.micromesh.bake_maps(resolution=128) == {"FINISHED"}
    obj = bpy.data.objects["rock_maps"]
    mat = obj.data.materials[0]
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    (link,) = bsdf.inputs["Base Color"].links
    carried = link.from_node.image
    assert carried.name == "rock_maps_basecolor" and carried.packed_file is not None
    assert carried.colorspace_settings.name == img.colorspace_settings.name
    (rlink,) = bsdf.inputs["Roughness"].links
    assert rlink.from_node.image.name == "rock_maps_roughness"
    assert rlink.from_node.image.colorspace_settings.name == "Non-Color"
    assert bsdf.inputs["Metallic"].default_value == pytest.approx(0.7)
    from micromesh.operators import result_files, source_texture

    textures = source_texture.read(src)
    assert [t.socket for t in textures.images] == ["Base Color", "Roughness"]
    size = rlink.from_node.image.size[0]
    got_r = np.empty(size * size * 4, np.float32)
    rlink.from_node.image.pixels.foreach_get(got_r)
    got_r = got_r.reshape(size, size, 4)
    mr = result_files.gltf_textures(textures, [np.zeros((size, size, 4)), got_r])
    assert set(mr) == {"baseColorTexture", "metallicRoughnessTexture"}
    np.testing.assert_allclose(mr["metallicRoughnessTexture"][..., 1], got_r[..., 0], atol=1e-6)
    assert np.all(mr["metallicRoughnessTexture"][..., 2] == np.float32(0.7))
    got = np.empty(128 * 128 * 4, np.float32)
    carried.pixels.foreach_get(got)
    got = got.reshape(128, 128, 4)
    # At each corner of the maps object, the carried texture holds about the colour the
    # source shows at its nearest point (base vertices: the micro-surface is near them).
    from micromesh.core.spatial.bake import nearest_points
    from micromesh.core.maps import sample
    from micromesh.core.spatial.barycentric import barycentrics

    me = obj.data
    uv_maps = np.empty(2 * len(me.loops), np.float32)
    me.uv_layers["UVMap"].data.foreach_get("uv", uv_maps)
    corner_vertex = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", corner_vertex)
    pos = bl_mesh.mesh_arrays(me)[0][corner_vertex]          # maps object: identity transform
    ref, ref_uv = bl_mesh.mesh_to_arrays(src), bl_mesh.mesh_uvs(src)
    near, face, _ = nearest_points(pos, ref)
    b = barycentrics(near, ref.vertices[ref.faces[face]])
    want = sample(pixels.astype(np.float64), np.einsum("qk,qkc->qc", b, ref_uv[face]))[:, :3]
    have = sample(got.astype(np.float64), uv_maps.reshape(-1, 2).astype(np.float64))[:, :3]
    close = np.abs(have - want).max(1) < 0.1
    assert close.mean() > 0.8, close.mean()
    assert np.ptp(have[:, 0]) > 0.5                          # a texture, not one colour
    have_r = sample(got_r.astype(np.float64), uv_maps.reshape(-1, 2).astype(np.float64))[:, 0]
    assert (np.abs(have_r - want[:, 1]) < 0.1).mean() > 0.8  # roughness: the source's v


@pytest.mark.slow
def test_bake_maps_carries_the_source_normal_map_through_a_normal_map_node(scene):
    """A source whose Principled BSDF's Normal comes from a tangent-space Normal Map node of an
    image (flat: RGB 0.5, 0.5, 1) at strength 0.6: the maps object's material gets that map on
    its own atlas (non-colour data, beside the micro-detail map, not over it) through a Normal
    Map node of the atlas' UVs at the same strength; a flat map stays flat. For engines the
    base's normal map is the source's shading in the base's frame: the relief, tilted as the
    micro-detail map tilts."""
    src = scene.micromesh.source
    me = src.data
    corner_vertex = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", corner_vertex)
    p = bl_mesh.mesh_arrays(me)[0][corner_vertex]
    me.uv_layers.new(name="UVMap").data.foreach_set(
        "uv", (0.5 + 0.4 * p[:, :2]).astype(np.float32).reshape(-1))
    img = bpy.data.images.new("bumps", 16, 16)
    img.colorspace_settings.name = "Non-Color"
    img.pixels.foreach_set(np.tile([0.5, 0.5, 1.0, 1.0], 256).astype(np.float32))
    mat = bpy.data.materials.new("bumpy")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nodes, link = mat.node_tree.nodes, mat.node_tree.links.new
    tex, nmap = nodes.new("ShaderNodeTexImage"), nodes.new("ShaderNodeNormalMap")
    tex.image = img
    nmap.inputs["Strength"].default_value = 0.6
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    link(tex.outputs["Color"], nmap.inputs["Color"])
    link(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    src.data.materials.append(mat)
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    assert bpy.ops.micromesh.bake_maps(resolution=128) == {"FINISHED"}
    obj = bpy.data.objects[f"{src.name}_maps"]
    out = obj.data.materials[0]
    bsdf = next(n for n in out.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    (nlink,) = bsdf.inputs["Normal"].links
    node = nlink.from_node
    assert node.type == "NORMAL_MAP" and node.space == "TANGENT" and node.uv_map == "UVMap"
    assert node.inputs["Strength"].default_value == pytest.approx(0.6)
    carried = node.inputs["Color"].links[0].from_node.image
    assert carried.name == f"{src.name}_maps_sourcenormal"
    assert carried.colorspace_settings.name == "Non-Color"
    assert bpy.data.images.get(f"{src.name}_maps_normal") is not None   # the relief's, kept
    got = np.empty(128 * 128 * 4, np.float32)
    carried.pixels.foreach_get(got)
    got = got.reshape(-1, 4)[:, :3]
    # 0.5 as a byte is 128 / 255: a tilt of one step, turned into the atlas' frame, in steps
    assert np.abs(got - [0.5, 0.5, 1.0]).max() < 1.6 / 255
    from micromesh.operators import maps_work, result_files, source_texture

    textures = source_texture.read(src)
    assert [t.socket for t in textures.images] == ["Normal"]
    assert textures.normal_strength == pytest.approx(0.6)
    mm = writeback.load_outcome(bpy.data.objects[f"{src.name}_micromesh"]).micromesh
    baked = maps_work.bake_with_textures(mm, bl_mesh.mesh_to_arrays(src), 128, textures,
                                         lambda p: None, lambda: False, base_normal=True)
    maps = baked.maps
    assert baked.base_normal is not None and len(baked.carried) == 1
    engine = result_files.engine_normal_map(baked)[maps.filled] * 2 - 1
    relief = maps.normal[maps.filled] * 2 - 1
    assert np.median((engine * relief).sum(1)) > np.cos(np.radians(5))


@pytest.mark.slow
def test_bake_maps_uses_the_base_own_uv_map_where_it_has_one(scene):
    """A base with a UV map of its own (an artist's layout: here every triangle in a cell of
    its own) is baked on those UVs, seams and all; a map that lays every triangle on the
    same place is refused with a warning and a new atlas is made."""
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    res = bpy.data.objects["rock_micromesh"]
    base = res.micromesh_base
    me = base.data
    assert all(len(p.vertices) == 3 for p in me.polygons)
    n = int(np.ceil(np.sqrt(len(me.polygons))))
    cell = np.arange(len(me.polygons))
    x0, y0 = (cell % n) / n, (cell // n) / n
    corners = np.array([[0.1, 0.1], [0.9, 0.1], [0.1, 0.9]]) / n
    uv = np.stack([x0, y0], 1)[:, None, :] + corners[None]           # (faces, 3, 2)
    me.uv_layers.new(name="UVMap").data.foreach_set("uv", uv.astype(np.float32).reshape(-1))
    assert bpy.ops.micromesh.bake_maps(resolution=256) == {"FINISHED"}
    maps = bpy.data.objects["rock_maps"].data
    got = np.empty(2 * len(maps.loops), np.float32)
    maps.uv_layers["UVMap"].data.foreach_get("uv", got)
    np.testing.assert_allclose(got.reshape(-1, 3, 2), uv, atol=1e-6)
    stacked = np.broadcast_to(corners[None] * n, uv.shape)           # all on one place
    me.uv_layers["UVMap"].data.foreach_set("uv", stacked.astype(np.float32).reshape(-1))
    assert bpy.ops.micromesh.bake_maps(resolution=256) == {"FINISHED"}
    maps = bpy.data.objects["rock_maps"].data
    got = np.empty(2 * len(maps.loops), np.float32)
    maps.uv_layers["UVMap"].data.foreach_get("uv", got)
    assert not np.allclose(got.reshape(-1, 3, 2), stacked, atol=1e-3)     # a new atlas


@pytest.mark.slow
def test_a_base_made_by_blenders_decimate_inherits_the_source_uvs_and_bakes_on_them(scene):
    """Make Base with Blender's Decimate on a UV-mapped source (a grid whose UVs are its x, y
    scaled into the unit square) gives a base carrying those UVs; Bake Maps then lays the maps
    out on them rather than on a new atlas."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=24, y_subdivisions=24, size=2.0,
                                    calc_uvs=True)
    grid = bpy.context.active_object
    grid.name = "sheet"
    s = scene.micromesh
    s.source, s.base, s.base_method, s.decimate_mode, s.ratio = grid, None, "BLENDER", "RATIO", 0.25
    assert bpy.ops.micromesh.make_base() == {"FINISHED"}
    base = s.base
    uv = bl_mesh.corner_uvs(base.data)
    v, f = bl_mesh.mesh_arrays(base.data)
    np.testing.assert_allclose(uv, (v[f][..., :2] + 1.0) / 2.0, atol=1e-5)   # the source's map
    assert bpy.ops.micromesh.construct(method="PROJECTION") == {"FINISHED"}
    assert bpy.ops.micromesh.bake_maps(resolution=128) == {"FINISHED"}
    maps = bpy.data.objects["sheet_maps"].data
    got = np.empty(2 * len(maps.loops), np.float32)
    maps.uv_layers["UVMap"].data.foreach_get("uv", got)
    np.testing.assert_allclose(got.reshape(-1, 3, 2), bl_mesh.corner_uvs(base.data), atol=1e-6)


def test_carried_emission_reaches_gltf_as_the_source_shows_it():
    """The emission colour goes into glTF's emissive texture times the source's Emission
    Strength (glTF's core emission stops at 1), and not at all where the strength is 0 (the
    source does not glow); a lone Metallic texture gets the source's Roughness beside it."""
    from micromesh.operators.result_files import gltf_textures
    from micromesh.operators.source_texture import SourceImage, SourceTextures

    px = np.full((4, 4, 4), 0.5, np.float32)
    images = [SourceImage("Emission Color", "Color", px, "sRGB", False),
              SourceImage("Metallic", "Color", px, "Non-Color", False)]
    carried = [np.full((8, 8, 4), 0.8, np.float32), np.full((8, 8, 4), 0.25, np.float32)]
    for strength, want in ((0.0, None), (0.5, 0.4), (3.0, 0.8)):
        tex = SourceTextures(None, None, images,
                             {"Metallic": 0.0, "Roughness": 0.3, "Emission Strength": strength})
        out = gltf_textures(tex, carried)
        if want is None:
            assert "emissiveTexture" not in out
        else:
            np.testing.assert_allclose(out["emissiveTexture"], want, rtol=1e-6)
        mr = out["metallicRoughnessTexture"]
        np.testing.assert_allclose(mr[..., 1], 0.3, rtol=1e-6)       # Roughness: the value
        np.testing.assert_allclose(mr[..., 2], 0.25, rtol=1e-6)      # Metallic: luminance


@pytest.mark.parametrize("fmt", ["stl", "usdc"])
@pytest.mark.slow
def test_an_stl_or_usd_imported_by_blender_constructs(scene, tmp_path, fmt):
    """The panel's inputs as Blender's own importers bring them in (STL: a mesh of its
    listed triangles; USD: an object under its file's transform): Construct builds on them."""
    path = tmp_path / f"ball.{fmt}"
    src = scene.micromesh.source
    if fmt == "stl":
        assert bpy.ops.wm.stl_export(filepath=str(path)) == {"FINISHED"}
    else:
        assert bpy.ops.wm.usd_export(filepath=str(path)) == {"FINISHED"}
    bpy.data.objects.remove(src)
    before = set(bpy.data.objects)
    if fmt == "stl":
        assert bpy.ops.wm.stl_import(filepath=str(path)) == {"FINISHED"}
    else:
        assert bpy.ops.wm.usd_import(filepath=str(path)) == {"FINISHED"}
    (obj,) = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    scene.micromesh.source = obj
    m = _construct(scene)
    assert m["reference_faces"] == 320 and np.isfinite(m["psnr"]) and m["psnr"] > 20
    tess = writeback.load_outcome(bpy.data.objects[f"{obj.name}_micromesh"]).micromesh
    x = tess.tessellate().vertices
    np.testing.assert_allclose((x.max(0) + x.min(0)) / 2, (1.0, 0.0, 0.0), atol=0.05)


def test_infinite_coordinates_are_refused_in_one_line(scene):
    src = scene.micromesh.source
    co = _vertices(src.data).copy()
    co[[3, 7, 9]] = np.inf
    src.data.vertices.foreach_set("co", co.reshape(-1))
    src.data.update()
    with pytest.raises(RuntimeError) as e:
        bpy.ops.micromesh.construct(method="OPTIMIZE")
    text = str(e.value).strip()
    assert "'rock': 3 of 162 vertices have NaN or infinite coordinates" in text
    assert len(text.splitlines()) == 1 and "rock_micromesh" not in bpy.data.objects
