"""A file we read ourselves goes straight into the construction's arrays: the mesh that
``operators.sources.import_source`` hands over is, to the bit, what Blender's object of it
reads back (``bl_mesh.mesh_to_arrays``), near the origin and far from it; a file Blender
reads is handed over as None."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
import micromesh_path  # noqa: E402

micromesh_path.ensure_package()
from micromesh.core.io.ply import write_ply  # noqa: E402
from micromesh.core.mesh.primitives import noisy_sphere  # noqa: E402
from micromesh.operators import bl_mesh, sources  # noqa: E402

pytestmark = pytest.mark.usefixtures("registered_addon")


@pytest.mark.parametrize("offset", [0.0, 3.0e6])
def test_a_mesh_we_read_is_what_blender_reads_back(tmp_path, offset):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    v, f = noisy_sphere(320)
    v = v * 0.37 + offset + np.array([0.1, -0.2, 0.3])
    path = tmp_path / "far.ply"
    write_ply(path, v, f, double=True)
    obj, mesh = sources.import_source(path)
    back = bl_mesh.mesh_to_arrays(obj)
    assert mesh is not None
    assert mesh.vertices.tobytes() == back.vertices.tobytes()
    assert np.array_equal(mesh.faces, back.faces)
    assert np.abs(mesh.vertices - v).max() <= 1e-6 * np.ptp(v, axis=0).max()


def test_every_importer_the_table_names_is_here():
    from micromesh.core.io import inputs

    assert set(sources._IMPORTERS) == set(inputs.IMPORTERS)
    assert {f.importer for f in inputs.INPUTS.values()} - {None} <= set(sources._IMPORTERS)


def test_a_file_blender_reads_is_read_back(tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    path = tmp_path / "cube.blend"
    bpy.ops.mesh.primitive_cube_add()
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    obj, mesh = sources.import_source(path)
    assert mesh is None and len(obj.data.polygons) == 6
