"""``batch.py --ray``'s pieces that need neither Blender nor a cluster: its usage errors, a
task's command line and memory, the worker's side of a task. (The real local cluster, and the
serial run's --resume: tests/blender/test_ray_cluster.py.)"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from core.io.ply import write_ply
from core.mesh.primitives import noisy_sphere

ROOT = Path(__file__).resolve().parents[2]


def batch(*args, timeout=300, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "batch.py"), *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT, env=env)


@pytest.mark.parametrize("args, reason", [
    (["--ray", "auto"], "--ray needs --input"),
    (["--input", "{lib}", "--ray", "127.0.0.1:1"], "--ray 127.0.0.1:1"),
])
@pytest.mark.slow
def test_ray_usage_errors_are_one_line(tmp_path, args, reason):
    """Before any work: the demo is refused, an address nobody answers at is said at once
    (or, without the ray package, that it is missing); exit 2."""
    lib = tmp_path / "lib"
    lib.mkdir()
    write_ply(lib / "a.ply", *noisy_sphere(320))
    r = batch(*[a.replace("{lib}", str(lib)) for a in args], "--output", tmp_path / "out",
              timeout=120)
    lines = [line for line in r.stderr.splitlines() if line.startswith("batch.py: error:")]
    assert r.returncode == 2 and len(lines) == 1, r.stdout + r.stderr
    assert reason in lines[0] or "requirements-ray.txt" in lines[0], lines[0]
    assert "Traceback" not in r.stderr


def test_each_input_runs_with_the_drivers_options(tmp_path):
    """The command line of one input's run: every option the driver was given except its own
    (--ray, --resume, --force, --threads, --input, --output), then the input, the folder,
    its result name (two inputs sharing a stem), the task's threads and --force."""
    import micromesh_path

    micromesh_path.ensure_package()
    from micromesh.cli.args import parse_args, parser
    from micromesh.cli.ray_submit import one_input_argv
    from micromesh.core.io.output_set import OutputSet

    args = parse_args(["--input", "lib", "--output", str(tmp_path), "--ray", "auto",
                       "--resume", "--threads", "2", "--preset", "fast", "--set", "seed=3",
                       "--set", "iterations=9", "--ply", "--budget", "300kB", "--ratio", "0.05"])
    out = OutputSet(tmp_path, "a_obj", [".blend", ".metrics.json"])
    argv = one_input_argv(args, Path("lib/a.obj"), out)
    again = parser().parse_args(argv)
    assert again.input == str(Path("lib/a.obj").resolve())
    assert again.output == str(tmp_path.resolve()) and again.result_name == "a_obj"
    assert again.threads == 2 and again.force and again.ray is None and not again.resume
    for key in ("preset", "overrides", "ply", "budget", "ratio", "method", "export"):
        assert getattr(again, key) == getattr(args, key), key


def test_task_memory_counts_the_triangles(tmp_path):
    """The memory a task asks for: the estimate of the input's triangle count, read from a
    PLY's header, an OBJ's faces (a quad is two), a binary STL's size (the input formats'
    table, ``core.io.inputs``), else from the file's size."""
    from core.io.inputs import count_triangles as triangles
    from core.io.stl import read_stl

    v, f = noisy_sphere(1280)
    write_ply(tmp_path / "a.ply", v, f)
    assert triangles(tmp_path / "a.ply") == len(f)
    (tmp_path / "q.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 1 2 3\n")
    assert triangles(tmp_path / "q.obj") == 3
    stl = bytearray(80) + (2).to_bytes(4, "little") + bytes(100)
    (tmp_path / "b.stl").write_bytes(bytes(stl))
    assert triangles(tmp_path / "b.stl") == 2 == len(read_stl(tmp_path / "b.stl")[1])
    (tmp_path / "c.fbx").write_bytes(bytes(2000))
    assert triangles(tmp_path / "c.fbx") == 100


@pytest.mark.slow
def test_a_task_reports_its_run_and_raises_for_a_killed_one(tmp_path):
    """The worker's side without Ray: an earlier attempt's temporaries removed, batch.py's
    error lines and exit status returned, a run killed by a signal raised (Ray retries it)."""
    import micromesh_path

    micromesh_path.ensure_package()
    from micromesh.cli.ray_task import ChildKilled, run_input

    stale = tmp_path / ".a.partial-123.blend"
    stale.write_bytes(b"half")
    fails = tmp_path / "fails.py"
    fails.write_text("print('[a] reading')\nprint('batch.py: error: a.ply: bad')\n"
                     "raise SystemExit(1)\n")
    r = run_input(str(fails), [], str(tmp_path), "a", ".metrics.json", False)
    assert r["rc"] == 1 and r["errors"] == ["batch.py: error: a.ply: bad"]
    assert r["tail"][0] == "[a] reading" and not stale.exists()
    killed = tmp_path / "killed.py"
    killed.write_text("import os, signal\nos.kill(os.getpid(), signal.SIGKILL)\n")
    with pytest.raises(ChildKilled, match="SIGKILL"):
        run_input(str(killed), [], str(tmp_path), "a", ".metrics.json", False)
    r = run_input(str(tmp_path / "none.py"), [], str(tmp_path), "a", ".metrics.json", False)
    assert r["rc"] == 2 and "same path" in r["errors"][0]
