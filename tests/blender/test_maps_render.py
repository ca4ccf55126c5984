"""The maps object renders its displacement in Cycles: on Blender 5.0 through adaptive
subdivision and the material's Displacement node, on 4.2-4.5 through the Geometry Nodes
modifier. A square base carries a height map with one bump; an orthographic camera sees the
square edge-on, so only the displacement can put pixels above its edge, and the bump's top
lands where its height says."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

import micromesh_path  # noqa: E402

micromesh_path.ensure_package()
from micromesh.core.maps import Atlas, Maps  # noqa: E402
from micromesh.core.mesh.trimesh import TriMesh  # noqa: E402
from micromesh.core.micro.micromesh import MicroMesh  # noqa: E402
from micromesh.operators import maps_object  # noqa: E402

RES, PIXELS, SCALE = 64, 48, 2.4     # map texels; image pixels; the camera's ortho width
PEAK = 0.5                           # the bump's height, world units


def _square() -> tuple[MicroMesh, Maps]:
    """A 2 x 2 square in z = 0 (directions +z) with UVs over the unit square and a height
    map holding a bump of ``PEAK`` at (u, v) = (0.5, 0.5)."""
    base = TriMesh(np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]),
                   np.array([[0, 1, 2], [0, 2, 3]]))
    mm = MicroMesh.flat(base, [0, 0], directions=np.tile([0.0, 0.0, 1.0], (4, 1)))
    atlas = Atlas(np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]]), base.faces.copy(), np.arange(4))
    y, x = (np.mgrid[0:RES, 0:RES] + 0.5) / RES
    height = PEAK * np.exp(-((x - 0.5) ** 2 + (y - 0.5) ** 2) / 0.02)
    maps = Maps(atlas, height.astype(np.float32), np.full((RES, RES, 3), 0.5, np.float32),
                np.ones((RES, RES), bool), {"level": 5})
    return mm, maps


def _silhouette(scene) -> np.ndarray:
    """(H, W) alpha of a Cycles render of ``scene``, row 0 at the bottom."""
    scene.render.filepath = "//unused"
    bpy.ops.render.render()
    result = bpy.data.images["Render Result"]
    path = bpy.app.tempdir + "silhouette.png"
    result.save_render(filepath=path)
    img = bpy.data.images.load(path)
    alpha = np.array(img.pixels[:]).reshape(PIXELS, PIXELS, 4)[..., 3]
    bpy.data.images.remove(img)
    return alpha


@pytest.fixture
def scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device, sc.cycles.samples, sc.cycles.use_denoising = "CPU", 1, False
    sc.render.resolution_x = sc.render.resolution_y = PIXELS
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = True
    sc.render.image_settings.file_format = "PNG"
    sc.render.image_settings.color_mode = "RGBA"
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", SCALE
    cam.location, cam.rotation_euler = (5.0, 0.0, 0.0), (np.pi / 2, 0.0, np.pi / 2)
    sc.collection.objects.link(cam)
    sc.camera = cam
    return sc


def test_the_maps_object_renders_its_displacement_in_cycles(scene):
    mm, maps = _square()
    obj = maps_object.maps_object(bpy.context, None, mm, maps, "square_maps")
    mod = obj.modifiers[maps_object.MODIFIER]
    if bpy.app.version >= (5, 0, 0):          # Cycles' own adaptive subdivision
        assert mod.type == "SUBSURF" and mod.use_adaptive_subdivision
        assert mod.subdivision_type == "SIMPLE"
        assert obj.data.materials[0].displacement_method == "DISPLACEMENT"
    else:                                     # the Geometry Nodes path
        assert mod.type == "NODES"
    alpha = _silhouette(scene)
    rows = np.flatnonzero((alpha > 0.5).any(1))
    assert len(rows), "nothing rendered: the square is edge-on, only displacement shows"
    top = (rows.max() + 1) / PIXELS * SCALE - SCALE / 2      # world height of the top row
    assert abs(top - PEAK) < 2 * SCALE / PIXELS, (top, PEAK)
    # no height, no pixels: the check can fail
    maps.height[:] = 0.0
    maps_object.maps_object(bpy.context, None, mm, maps, "square_maps")
    assert not (_silhouette(scene) > 0.5).any()
