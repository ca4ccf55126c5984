"""A glTF checked before Blender's importer reads it (core.io.gltf_check): each broken file
refused in one line naming the cause; good files (GLB, external and data-URI buffers)
pass."""
from __future__ import annotations

import base64
import json

import numpy as np
import pytest

from core.io.gltf import GltfError
from core.io.gltf_check import check_gltf
from core.mesh.primitives import icosphere
from corpus import write_gltf

V, F = icosphere(2)                   # 42 vertices, 80 faces


def write(path, vertices=V, faces=F, edit=None):
    """A plain glTF of the icosphere (``.glb``, or ``.gltf`` + ``.bin``); ``edit(doc)``
    changes its JSON first."""
    return write_gltf(path, vertices, faces, edit)


def test_good_files_pass(tmp_path):
    check_gltf(write(tmp_path / "a.glb"))
    check_gltf(write(tmp_path / "b.gltf"))
    c = write(tmp_path / "c.gltf")
    doc = json.loads(c.read_text())
    doc["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                + base64.b64encode(c.with_suffix(".bin").read_bytes()).decode())
    c.with_suffix(".bin").unlink()
    c.write_text(json.dumps(doc))
    check_gltf(c)                                        # an embedded buffer is read


def _set(path, value):
    """``edit`` that sets doc[path...] = value."""
    def edit(doc):
        d = doc
        for k in path[:-1]:
            d = d[k]
        d[path[-1]] = value
    return edit


@pytest.mark.parametrize("name, kw, reason", [
    ("inf.glb", dict(vertices=np.full_like(V, np.inf)),
     "42 of 42 vertices have NaN or infinite positions"),
    ("nan.gltf", dict(vertices=np.where(np.arange(42)[:, None] == 5, np.nan, V)),
     "1 of 42 vertices have NaN or infinite"),
    ("index.glb", dict(faces=np.where(np.arange(80)[:, None] == 3, 52, F)),
     "face index 52 is out of range (42 vertices)"),
    ("count.gltf", dict(edit=_set(["accessors", 0, "count"], "many")), "not valid glTF"),
    ("long.glb", dict(edit=_set(["accessors", 0, "count"], 4200)), "reads past its bufferView"),
    ("node.glb", dict(edit=_set(["scenes", 0, "nodes"], [3])), "nodes[3] does not exist"),
    ("mesh.glb", dict(edit=_set(["nodes", 0, "mesh"], 2)), "meshes[2] does not exist"),
    ("cycle.glb", dict(edit=_set(["nodes"], [{"mesh": 0, "children": [1]}, {"children": [0]}])),
     "its own ancestor"),
    ("mode.glb", dict(edit=_set(["meshes", 0, "primitives", 0, "mode"], 9)),
     "mode 9 is not a glTF mode"),
    ("move.glb", dict(edit=_set(["nodes", 0, "translation"], [0, float("inf"), 0])),
     "node 0's transform is NaN or infinite"),
])
def test_a_broken_gltf_is_refused_in_one_line(tmp_path, name, kw, reason):
    path = write(tmp_path / name, **kw)
    with pytest.raises(GltfError) as e:
        check_gltf(path)
    assert reason in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_missing_buffer_and_not_json(tmp_path):
    path = write(tmp_path / "a.gltf")
    path.with_suffix(".bin").unlink()
    with pytest.raises(GltfError, match="the file it names, a.bin, is missing"):
        check_gltf(path)
    (tmp_path / "b.gltf").write_text('{"asset": {"version": "2.0"}, "meshes": [ nope ]')
    with pytest.raises(GltfError, match="not valid glTF JSON"):
        check_gltf(tmp_path / "b.gltf")


def test_compressed_primitives_are_left_to_blender(tmp_path):
    """A Draco primitive's accessors have no bufferView: not read here, not refused."""
    def draco(doc):
        prim = doc["meshes"][0]["primitives"][0]
        prim["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {}}}
        for a in doc["accessors"]:
            del a["bufferView"]
    check_gltf(write(tmp_path / "d.glb", vertices=np.full_like(V, np.inf), edit=draco))
