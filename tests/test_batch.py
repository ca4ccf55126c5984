"""batch.py over a folder of mixed inputs in a subprocess, and its one-line errors."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from test_manifest import ROOT  # noqa: E402


def run_batch(*args, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "batch.py"), *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT)


def _error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("batch.py: error:")]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A folder with a .ply, an .obj, a .glb and a .blend, all made here with bpy."""
    folder = tmp_path_factory.mktemp("inputs")
    import addon_utils

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=4)
    bpy.ops.wm.ply_export(filepath=str(folder / "ball.ply"), ascii_format=False)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_monkey_add()
    bpy.context.active_object.modifiers.new("s", "SUBSURF").levels = 1
    bpy.ops.wm.obj_export(filepath=str(folder / "monkey.obj"), export_materials=False)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_torus_add(major_segments=48, minor_segments=16)
    addon_utils.enable("io_scene_gltf2", default_set=True)
    bpy.ops.export_scene.gltf(filepath=str(folder / "ring.glb"), export_format="GLB")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cylinder_add(vertices=64)
    bpy.context.active_object.modifiers.new("s", "SUBSURF").levels = 2
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "can.blend"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    (folder / "notes.txt").write_text("not a mesh")
    return folder


def test_batch_over_a_folder(inputs, tmp_path):
    out = tmp_path / "out"
    r = run_batch("--input", inputs, "--output", out, "--method", "projection", "--level", "2",
                  "--target-faces", "80", "--ply")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "done: 4/4" in r.stdout
    for name in ("ball", "monkey", "ring", "can"):
        metrics = json.loads((out / f"{name}.metrics.json").read_text())
        assert metrics["object"] == f"{name}_micromesh" and metrics["method"] == "projection"
        m = metrics["metrics"]
        assert m["micro_triangles"] == 16 * m["base_faces"] and m["shell_volume"] > 0
        assert abs(m["base_faces"] - 80) <= 10
        assert (out / f"{name}_micromesh.ply").stat().st_size > 0
        bpy.ops.wm.open_mainfile(filepath=str(out / f"{name}.blend"))
        obj = bpy.data.objects[f"{name}_micromesh"]
        assert obj.get("micromesh_data") is not None
        assert len(obj.data.polygons) == m["micro_triangles"]
        assert bpy.data.objects[f"{name}_base"].data.attributes.get("micromesh_level") is not None
    from micromesh_path import ensure_package

    ensure_package()
    from micromesh.core.meshio import read_mesh

    ply = read_mesh(out / "ball_micromesh.ply")
    assert ply.n_faces == 16 * json.loads((out / "ball.metrics.json").read_text())["metrics"]["base_faces"]
    assert np.allclose(np.linalg.norm(ply.vertices, axis=1), 1.0, atol=0.02)  # on the sphere
    bpy.ops.wm.read_factory_settings(use_empty=True)


@pytest.mark.parametrize("args, reason", [
    (["--input", "/no/such/file.ply"], "input not found"),
    (["--input", "{inputs}/notes.txt"], "unsupported file type"),
    (["--preset", "turbo"], "unknown preset"),
    (["--set", "iterations=many"], "iterations"),
    (["--set", "nonsense=1"], "unknown setting"),
    (["--level", "9"], "--level"),
])
def test_bad_input_exits_with_one_line(inputs, tmp_path, args, reason):
    args = [a.replace("{inputs}", str(inputs)) for a in args]
    r = run_batch(*args, "--output", tmp_path, timeout=120)
    assert r.returncode == 2, r.stdout + r.stderr
    lines = _error_lines(r.stderr)
    assert len(lines) == 1 and reason in lines[0], r.stderr
    assert "Traceback" not in r.stderr


def test_a_broken_file_in_a_folder_fails_alone(inputs, tmp_path):
    folder = tmp_path / "mixed"
    folder.mkdir()
    (folder / "broken.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n")
    (folder / "ball.ply").write_bytes((inputs / "ball.ply").read_bytes())
    r = run_batch("--input", folder, "--output", tmp_path / "out", "--method", "projection",
                  "--level", "1", "--target-faces", "40")
    assert r.returncode == 1, r.stdout + r.stderr
    assert "done: 1/2" in r.stdout and (tmp_path / "out" / "ball.blend").exists()
    lines = _error_lines(r.stderr)
    assert len(lines) == 1 and "broken" in lines[0]
