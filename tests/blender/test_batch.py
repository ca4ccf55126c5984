"""batch.py over a folder of mixed inputs in a subprocess, and its one-line errors."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from core.io.file_size import mmt_file_bytes  # noqa: E402
from core.lod.expansion import expansion_levels, nominal_expansion_bytes  # noqa: E402
from core.mesh.trimesh import TriMesh  # noqa: E402
from corpus import write_gltf  # noqa: E402
from test_manifest import ROOT  # noqa: E402

pytestmark = pytest.mark.slow     # batch.py in a process of its own


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
                  "--target-faces", "80", "--base-error", "0", "--ply")
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
    from micromesh.core.io.mesh_files import read_mesh

    from micromesh.core.io.micromesh_import import read_micromesh

    ply = read_mesh(out / "ball_micromesh.ply")
    assert ply.n_faces == 16 * json.loads((out / "ball.metrics.json").read_text())["metrics"]["base_faces"]
    assert np.allclose(np.linalg.norm(ply.vertices, axis=1), 1.0, atol=0.02)  # on the sphere
    for name in ("ball", "monkey", "ring", "can"):
        m = json.loads((out / f"{name}.metrics.json").read_text())["metrics"]
        assert m["export"]["files"] == [f"{name}.bary", f"{name}.bin", f"{name}.gltf"]
        mm = read_micromesh(out / f"{name}.gltf").micromesh()
        assert mm.topology.n_triangles == m["micro_triangles"]
        assert 0 < m["export"]["quantization_rms"] <= m["export"]["quantization_max"] < 5e-3
        if name == "ball":   # a PLY: the export is in the file's own coordinates
            tess = mm.tessellate()
            assert len(tess.vertices) == ply.n_vertices
            assert np.abs(np.sort(tess.vertices, 0) - np.sort(ply.vertices, 0)).max() < 5e-3
        if name == "ring":   # a glTF (Y-up) read by Blender's importer: exported Y-up again
            ext = np.ptp(mm.base.vertices, axis=0)
            assert ext[1] < 0.5 * ext[0] and ext[1] < 0.5 * ext[2]
    bpy.ops.wm.read_factory_settings(use_empty=True)


def test_a_micromesh_gltf_is_a_reference(inputs, tmp_path):
    """batch.py exports a micro-mesh, then takes that glTF as an input: the reference is its
    tessellation, in its own coordinates."""
    first, second = tmp_path / "first", tmp_path / "second"
    r = run_batch("--input", inputs / "ball.ply", "--output", first, *QUICK, "--export", "glb")
    assert r.returncode == 0, r.stdout + r.stderr
    m1 = json.loads((first / "ball.metrics.json").read_text())["metrics"]
    r = run_batch("--input", first / "ball.glb", "--output", second, *QUICK)
    assert r.returncode == 0, r.stdout + r.stderr
    m2 = json.loads((second / "ball.metrics.json").read_text())["metrics"]
    assert m2["reference_faces"] == m1["micro_triangles"]


@pytest.mark.parametrize("args, reason", [
    (["--input", "/no/such/file.ply"], "input not found"),
    (["--input", "{inputs}/notes.txt"], "unsupported file type"),
    (["--preset", "turbo"], "unknown preset"),
    (["--set", "iterations=many"], "iterations"),
    (["--set", "nonsense=1"], "unknown setting"),
    (["--level", "9"], "--level"),
    (["--budget", "lots"], "--budget"),
    (["--budget", "-2x"], "--budget"),
    (["--ratio", "1.5"], "--ratio"),
    (["--symmetry", "X"], "--symmetry"),
    (["--level", "3"], "--method projection"),
    (["--threads", "-2"], "--threads"),
    (["--set", "seed=1.7"], "'seed'"),
    (["--set", "preset=turbo"], "'preset'"),
    (["--set", "tau_in=nan"], "'tau_in'"),
    (["--set", "iterations=inf"], "'iterations'"),
    (["--set", "lr_base=nan"], "'lr_base'"),
    (["--set", "camera_radius=0"], "'camera_radius'"),
    (["--set", "betas=0.9"], "'betas'"),
    (["--set", "eval_views=0"], "'eval_views'"),
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
                  "--level", "1", "--target-faces", "40", "--base-error", "0")
    assert r.returncode == 1, r.stdout + r.stderr
    assert "done: 1/2" in r.stdout and (tmp_path / "out" / "ball.blend").exists()
    lines = _error_lines(r.stderr)
    assert len(lines) == 1 and "broken" in lines[0]


def test_budget_and_base_options_become_settings():
    from micromesh_path import ensure_package

    ensure_package()
    from micromesh.cli import args as batch    # batch.py's options (cli/args.py)

    assert batch.budget_overrides("2.5x") == ["budget_ratio=2.5", "budget_micro_triangles=0",
                                              "budget_bytes=0"]
    assert "budget_micro_triangles=150000" in batch.budget_overrides("150000")
    assert "budget_bytes=300000" in batch.budget_overrides("300kB")
    assert "budget_bytes=2000000" in batch.budget_overrides("2 MB")
    assert "budget_ratio=0.0" in batch.budget_overrides("0")          # no budget at all
    args = batch.parse_args(["--ratio", "0.05", "--base-error", "2e-3"])
    assert batch.base_overrides(args) == ["base_ratio=0.05", "base_faces=0", "base_max_error=0.002"]


def test_defaults_build_a_faithful_base_within_the_budget(inputs, tmp_path):
    """No options but the quick preset: the seams welded, the base keeps the torus's genus,
    the micro-mesh spends about twice the input's faces (its budget), and the .blend holds
    the base it was built on."""
    out = tmp_path / "out"
    src = tmp_path / "in"
    src.mkdir()
    (src / "ring.glb").write_bytes((inputs / "ring.glb").read_bytes())
    r = run_batch("--input", src / "ring.glb", "--output", out, "--preset", "fast",
                  "--set", "iterations=30", "--set", "subdivide_at=5,10,20", timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    m = json.loads((out / "ring.metrics.json").read_text())["metrics"]
    assert m["base"]["topology_base"] == m["base"]["topology_input"]
    assert m["base"]["topology_base"]["genus"] == 1
    # glTF splits vertices at UV seams: welded, and said (nothing else to warn of)
    assert len(m["warnings"]) == 1 and m["warnings"][0].endswith(" were welded")
    budget = m["budget"]["disk_bytes"]
    assert 0.75 * budget <= m["bytes"] <= budget
    assert "-> base" in r.stdout
    bpy.ops.wm.open_mainfile(filepath=str(out / "ring.blend"))
    base = bpy.data.objects["ring_base"]
    assert len(base.data.polygons) == m["base_faces"]
    v = np.array([x.co[:] for x in base.data.vertices])
    f = np.array([p.vertices[:] for p in base.data.polygons])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    # the .bin + .bary micromesh-tools' microexpansion 2 would write on the base, or on the
    # base its decimation aims at where that is more (on the base as built: the one in the
    # file has moved a little since)
    levels = expansion_levels(TriMesh(v, f), m["reference_faces"], 2.0)
    expected = max(mmt_file_bytes(levels, len(v)),
                   nominal_expansion_bytes(m["reference_faces"], 2.0))
    assert budget == pytest.approx(expected, rel=0.02)


QUICK = ("--method", "projection", "--level", "1", "--target-faces", "40", "--base-error", "0")


def test_same_stem_inputs_keep_both_results_and_results_are_not_replaced(inputs, tmp_path):
    folder, out = tmp_path / "same", tmp_path / "out"
    folder.mkdir()
    (folder / "a.ply").write_bytes((inputs / "ball.ply").read_bytes())
    (folder / "a.obj").write_bytes((inputs / "monkey.obj").read_bytes())
    r = run_batch("--input", folder, "--output", out, *QUICK)
    assert r.returncode == 0 and "done: 2/2" in r.stdout, r.stdout + r.stderr
    faces = {json.loads((out / f"{n}.metrics.json").read_text())["metrics"]["reference_faces"]
             for n in ("a_obj", "a_ply")}
    assert len(faces) == 2                                   # two different results
    assert sorted(p.name for p in out.iterdir()) == sorted(
        f"{n}{s}" for n in ("a_obj", "a_ply")
        for s in (".blend", ".gltf", ".bin", ".bary", ".report.png", ".report.json",
                  ".metrics.json"))
    before = (out / "a_ply.metrics.json").read_text()
    again = run_batch("--input", folder, "--output", out, *QUICK, timeout=120)
    assert again.returncode == 2 and "--force" in _error_lines(again.stderr)[0], again.stderr
    assert (out / "a_ply.metrics.json").read_text() == before and "[a" not in again.stdout
    forced = run_batch("--input", folder, "--output", out, *QUICK, "--force")
    assert forced.returncode == 0, forced.stderr
    assert json.loads((out / "a_ply.metrics.json").read_text())["name"] == "a_ply"


def test_an_unusable_output_folder_is_refused_before_any_work(inputs, tmp_path):
    (tmp_path / "file").write_text("x")
    r = run_batch("--input", inputs / "ball.ply", "--output", tmp_path / "file" / "out", *QUICK,
                  timeout=120)
    assert r.returncode == 2 and "cannot write to the output folder" in r.stderr, r.stderr
    assert "[ball]" not in r.stdout and "Traceback" not in r.stderr


def test_ctrl_c_exits_130_in_one_line_and_leaves_no_files(inputs, tmp_path):
    import signal

    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, str(ROOT / "batch.py"), "--input", inputs / "ball.ply",
                          "--output", out, "--preset", "fast", "--set", "iterations=100000",
                          "--set", "time_limit_s=0"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    for line in p.stdout:
        if "optimize" in line:
            break
    p.send_signal(signal.SIGINT)    # the construction stops at its next iteration
    try:
        _, err = p.communicate(timeout=300)
    except subprocess.TimeoutExpired:
        p.kill()
        raise AssertionError("batch.py did not stop within 300 s of Ctrl-C: " + p.communicate()[1][-2000:])
    assert p.returncode == 130, err
    assert err.strip().splitlines()[-1] == "batch.py: interrupted" and "Traceback" not in err
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("body, reason", [
    ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
     "0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n", "NaN"),
    ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
     "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "out of range"),
    ("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "degenerate"),
    ("v 0 0 0\nv 1 0 0\n", "no faces"),
])
def test_bad_geometry_is_refused_not_repaired(tmp_path, body, reason):
    """Blender's importers turn NaN into 0 and drop bad faces; batch.py reads PLY/OBJ itself
    and refuses them, and refuses an input with no surface, in one line (exit 1)."""
    f = tmp_path / ("bad.obj" if body.startswith("v ") else "bad.ply")
    f.write_text(body)
    r = run_batch("--input", f, "--output", tmp_path / "out", *QUICK, timeout=120)
    assert r.returncode == 1, r.stdout + r.stderr
    lines = _error_lines(r.stderr)
    assert len(lines) == 1 and reason in lines[0], r.stderr
    assert "Traceback" not in r.stderr and not list((tmp_path / "out").iterdir())


def test_maps_for_engines(inputs, tmp_path):
    """--maps: the maps object in the .blend, the height map fitted to the source as a 16-bit
    PNG (read by the glTF's KHR_materials_displacement and the USD's UsdUVTexture) and a
    half-float EXR, the 16-bit PNG normal map, the base as glTF and as USD, all in the
    result's set; the seams closed."""
    out = tmp_path / "out"
    r = run_batch("--input", inputs / "ball.ply", "--output", out, *QUICK, "--maps", "128",
                  "--export", "none")
    assert r.returncode == 0, r.stdout + r.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["ball.blend", "ball_height.png", "ball_height.exr", "ball_normal.png", "ball_base.gltf",
         "ball_base.bin", "ball.usda", "ball.report.png", "ball.report.json",
         "ball.metrics.json"])
    m = json.loads((out / "ball.metrics.json").read_text())["metrics"]
    assert m["maps"]["resolution"] == 128 and m["maps"]["level"] == 4
    assert max(m["maps"]["seam_gap_max"].values()) < 1e-5
    assert m["maps"]["bytes"]["_height.png"] == (out / "ball_height.png").stat().st_size
    png = (out / "ball_normal.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and png[16:26] == bytes.fromhex("00000080000000801002")
    height = (out / "ball_height.png").read_bytes()                   # 16-bit grey
    assert height[16:26] == bytes.fromhex("00000080000000801000")
    assert (out / "ball_height.exr").read_bytes()[:4] == b"\x76\x2f\x31\x01"   # OpenEXR magic
    from micromesh_path import ensure_package

    ensure_package()
    from micromesh.core.io.gltf import Document

    doc = Document(out / "ball_base.gltf")
    prim = doc.doc["meshes"][0]["primitives"][0]
    uv = doc.accessor(prim["attributes"]["TEXCOORD_0"])
    assert uv.min() >= 0 and uv.max() <= 1 and len(uv) == len(doc.accessor(prim["attributes"]
                                                                          ["POSITION"]))
    assert doc.doc["images"][0]["uri"] == "ball_normal.png"
    ext = doc.doc["materials"][0]["extensions"]["KHR_materials_displacement"]
    tex = doc.doc["textures"][ext["displacementGeometryTexture"]["index"]]
    assert doc.doc["images"][tex["source"]]["uri"] == "ball_height.png"
    assert ext["displacementGeometryFactor"] == pytest.approx(m["maps"]["height_factor"])
    assert "KHR_materials_displacement" in doc.doc["extensionsUsed"]
    assert "@ball_height.png@" in (out / "ball.usda").read_text()
    bpy.ops.wm.open_mainfile(filepath=str(out / "ball.blend"))
    assert bpy.data.objects["ball_maps"].modifiers.get("MicroMesh Height") is not None
    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert m["maps"]["own_uvs"] is False                       # the builder's base: a new atlas


@pytest.mark.parametrize("size", ["200k", "900k"])
def test_a_full_disk_fails_the_input_in_one_line_and_leaves_nothing(inputs, tmp_path, size):
    """The output folder on a filesystem of ``size`` (a tmpfs mounted in a user namespace of
    its own): 200k fills while the .blend is written, 900k while the maps' files are. The
    input fails in one line that says so, and no file of it, whole or partial, is left."""
    import shutil

    out = tmp_path / "small"
    out.mkdir()
    unshare = shutil.which("unshare")
    mount = f"mount -t tmpfs -o size={size} tmpfs {out}"
    probe = subprocess.run([unshare or "unshare", "--user", "--map-root-user", "--mount", "sh",
                            "-c", mount], capture_output=True, text=True) if unshare else None
    if probe is None or probe.returncode != 0:
        pytest.skip("no user namespace here to mount a small filesystem in")
    cmd = " ".join([sys.executable, str(ROOT / "batch.py"), "--input", str(inputs / "ball.ply"),
                    "--output", str(out), *QUICK, "--maps", "128"])
    r = subprocess.run([unshare, "--user", "--map-root-user", "--mount", "sh", "-c",
                        f"{mount} && {cmd}; rc=$?; ls -A {out}; exit $rc"],
                       capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode == 1, r.stdout + r.stderr
    lines = _error_lines(r.stderr)
    assert len(lines) == 1 and "No space left on device" in lines[0], r.stderr
    assert "Traceback" not in r.stderr
    assert r.stdout.strip().splitlines()[-1].startswith("done: 0/1"), r.stdout   # ls: empty


def test_maps_on_the_uvs_a_decimated_base_inherits(tmp_path):
    """--base-method blender carries the source's UVs onto the base, as Make Base does, and
    --maps lays the maps out on them (a grid whose UVs are its x, y in the unit square)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=24, y_subdivisions=24, size=2.0,
                                    calc_uvs=True)
    bpy.context.active_object.name = "sheet"
    src = tmp_path / "sheet.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(src))
    out = tmp_path / "out"
    r = run_batch("--input", src, "--output", out, "--base-method", "blender", "--method",
                  "projection", "--maps", "64", "--export", "none")
    assert r.returncode == 0, r.stdout + r.stderr
    m = json.loads((out / "sheet.metrics.json").read_text())["metrics"]
    assert m["maps"]["own_uvs"] is True and m["maps"]["atlas_note"] == ""
    bpy.ops.wm.open_mainfile(filepath=str(out / "sheet.blend"))
    maps = bpy.data.objects["sheet_maps"].data
    got = np.empty(2 * len(maps.loops), np.float32)
    maps.uv_layers["UVMap"].data.foreach_get("uv", got)
    corners = np.empty(3 * len(maps.polygons), np.int32)
    maps.polygons.foreach_get("vertices", corners)
    xy = np.empty(3 * len(maps.vertices), np.float32)
    maps.vertices.foreach_get("co", xy)
    xy = xy.reshape(-1, 3)[corners, :2]
    np.testing.assert_allclose(got.reshape(-1, 2), (xy + 1.0) / 2.0, atol=1e-5)
    bpy.ops.wm.read_factory_settings(use_empty=True)


def _write_stl(path, vertices, faces, ascii: bool) -> None:
    tri = vertices[faces]
    if ascii:
        lines = ["solid ball"]
        for t in tri:
            lines += ["facet normal 0 0 0", "outer loop"]
            lines += [f"vertex {x!r} {y!r} {z!r}" for x, y, z in t] + ["endloop", "endfacet"]
        path.write_text("\n".join(lines + ["endsolid ball", ""]))
        return
    rec = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tri
    path.write_bytes(b"solid ball: a binary STL".ljust(80) + np.uint32(len(tri)).tobytes()
                     + rec.tobytes())


def test_stl_and_usd_inputs(inputs, tmp_path):
    """Binary and ASCII STL (read by core.io, the file's own coordinates) and USD (Blender's
    importer; the file made by Blender's own exporter) build like the PLY they came from."""
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    ball = read_ply_mesh(inputs / "ball.ply")
    _write_stl(folder / "binary.stl", ball.vertices, ball.faces, ascii=False)
    _write_stl(folder / "ascii.stl", ball.vertices, ball.faces, ascii=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=4, location=(0.0, 0.0, 3.0))
    assert bpy.ops.wm.usd_export(filepath=str(folder / "ball.usdc")) == {"FINISHED"}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    r = run_batch("--input", folder, "--output", out, *QUICK)
    assert r.returncode == 0 and "done: 3/3" in r.stdout, r.stdout + r.stderr
    assert "USD" not in r.stdout + r.stderr                 # the importer's own lines
    from micromesh_path import ensure_package

    ensure_package()
    from micromesh.core.io.micromesh_import import read_micromesh

    for name in ("binary", "ascii", "ball"):
        m = json.loads((out / f"{name}.metrics.json").read_text())["metrics"]
        assert m["reference_faces"] == ball.n_faces and m["micro_triangles"] == 4 * m["base_faces"]
        base = read_micromesh(out / f"{name}.gltf").micromesh().base.vertices
        # on the unit sphere: STL in its own coordinates, USD moved by 3 along Blender's Z,
        # exported Y-up (Blender's frame, as Blender's glTF exporter writes it)
        centre = (0.0, 0.0, 0.0) if name != "ball" else (0.0, 3.0, 0.0)
        r = np.linalg.norm(base - centre, axis=1)            # a 40-face base: chords inside
        assert 0.9 < r.min() and r.max() < 1.02, name


def read_ply_mesh(path):
    from micromesh_path import ensure_package

    ensure_package()
    from micromesh.core.io.mesh_files import read_mesh

    return read_mesh(path)


def test_broken_and_non_finite_gltf_are_refused_in_one_line(inputs, tmp_path):
    """Infinite positions (Blender's importer makes them zeros), a face index out of range,
    a missing buffer file, JSON that does not parse, a value that is not a number: each
    refused in one line naming the cause, none of Blender's importer output or tracebacks;
    exit 1 with the good input done."""
    ball = read_ply_mesh(inputs / "ball.ply")
    v, f = ball.vertices, ball.faces
    folder = tmp_path / "in"
    folder.mkdir()
    write_gltf(folder / "inf.glb", np.full_like(v, np.inf), f)
    write_gltf(folder / "index.glb", v, np.where(np.arange(len(f))[:, None] == 3, len(v) + 9, f))
    write_gltf(folder / "nobuffer.gltf", v, f)
    (folder / "nobuffer.bin").unlink()
    (folder / "notjson.gltf").write_text('{"asset": {"version": "2.0"}, "meshes": [ nope ]')

    def count(doc):
        doc["accessors"][0]["count"] = "many"
    write_gltf(folder / "value.gltf", v, f, count)
    write_gltf(folder / "good.glb", v, f)
    r = run_batch("--input", folder, "--output", tmp_path / "out", *QUICK)
    assert r.returncode == 1 and "done: 1/6" in r.stdout, r.stdout + r.stderr
    lines = _error_lines(r.stderr)
    assert len(lines) == 5 and r.stderr.strip().splitlines() == lines, r.stderr
    want = {"inf.glb": f"{len(v)} of {len(v)} vertices have NaN or infinite positions",
            "index.glb": f"face index {len(v) + 9} is out of range ({len(v)} vertices)",
            "nobuffer.gltf": "the file it names, nobuffer.bin, is missing",
            "notjson.gltf": "not valid glTF JSON",
            "value.gltf": "not valid glTF (ValueError"}
    for name, reason in want.items():
        assert sum(f" {name}: " in ln and reason in ln for ln in lines) == 1, (name, lines)
    assert "Traceback" not in r.stdout and "INFO" not in r.stdout      # the importer's lines
    verbose = run_batch("--input", folder / "good.glb", "--output", tmp_path / "v", *QUICK,
                        "--verbose")
    assert verbose.returncode == 0 and "glTF import finished" in verbose.stdout + verbose.stderr


def test_far_from_the_origin_builds_as_at_the_origin(tmp_path):
    """A sphere at (1e6, -1e6, 1e6) in a double-precision PLY builds the base it builds at the
    origin (float32 in Blender's meshes blurred it to 0.06 there); the exports and the
    objects in the .blend lie where the input does, to 1e-4 of its diagonal."""
    from micromesh_path import ensure_package

    ensure_package()
    from micromesh.core.io.mesh_files import read_mesh, write_ply
    from micromesh.core.io.micromesh_import import read_micromesh
    from micromesh.core.mesh.primitives import noisy_sphere

    offset = np.array([1e6, -1e6, 1e6])
    v, f = noisy_sphere(2000)
    folder = tmp_path / "in"
    folder.mkdir()
    write_ply(folder / "near.ply", v, f, double=True)
    write_ply(folder / "far.ply", v + offset, f, double=True)
    out = tmp_path / "out"
    r = run_batch("--input", folder, "--output", out, "--preset", "fast", "--method",
                  "projection", "--level", "1", "--ply")
    assert r.returncode == 0, r.stdout + r.stderr
    m = {n: json.loads((out / f"{n}.metrics.json").read_text())["metrics"] for n in ("near", "far")}
    assert abs(m["far"]["base_faces"] - m["near"]["base_faces"]) <= 0.03 * m["near"]["base_faces"]
    diag = TriMesh(v, f).bbox_diagonal
    near, far = (read_micromesh(out / f"{n}.gltf").micromesh() for n in ("near", "far"))
    if near.base.n_vertices == far.base.n_vertices:
        assert np.abs(far.base.vertices - offset - near.base.vertices).max() < 1e-4 * diag
    from micromesh.core.spatial.bake import nearest_points

    ref = read_mesh(folder / "far.ply")
    for points in (far.base.vertices, read_mesh(out / "far_micromesh.ply").vertices):
        p, _, _ = nearest_points(points, ref)
        assert np.linalg.norm(p - points, axis=1).max() < 0.02 * diag     # near the input
    np.testing.assert_allclose(read_mesh(out / "far_micromesh.ply").vertices - offset,
                               read_mesh(out / "near_micromesh.ply").vertices, atol=1e-4 * diag)
    bpy.ops.wm.open_mainfile(filepath=str(out / "far.blend"))
    for name in ("far", "far_base", "far_micromesh"):
        obj = bpy.data.objects[name]
        co = np.empty(3 * len(obj.data.vertices), np.float32)
        obj.data.vertices.foreach_get("co", co)
        assert np.abs(co).max() < diag, name                         # centred data
        world = co.reshape(-1, 3).astype(np.float64) + np.array(obj.matrix_world.translation)
        p, _, _ = nearest_points(world, ref)
        assert np.linalg.norm(p - world, axis=1).max() < 0.02 * diag, name
    bpy.ops.wm.read_factory_settings(use_empty=True)
