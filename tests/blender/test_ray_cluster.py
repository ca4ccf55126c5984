"""``batch.py --ray`` on a real local Ray cluster (a head and two worker nodes on 127.0.0.1):
six inputs and a broken one, interrupted after the first result, then resumed with a worker
node killed while it runs an input; every result's files byte for byte those of the serial
run. The serial run's --resume. (--ray's usage errors, a task's command line and memory:
tests/core/test_ray_tasks.py.)"""
from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from core.io.ply import write_ply
from core.mesh.primitives import noisy_sphere, torus
from local_ray import LocalCluster
from test_manifest import ROOT

pytestmark = pytest.mark.slow     # batch.py and Ray's nodes in processes of their own

RAY = pytest.mark.skipif(importlib.util.find_spec("ray") is None,
                         reason="the ray package is not installed (requirements-ray.txt)")
BPY = pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="needs the bpy wheel")

# the optimiser (the default method), small enough for CI: a few seconds an input
TINY = ("--preset", "fast", "--target-faces", "40", "--base-error", "0",
        "--set", "time_limit_s=0", "--set", "iterations=8", "--set", "subdivide_at=2,5",
        "--set", "n_views=8", "--set", "train_resolution=64", "--set", "lod_resolution=64",
        "--set", "eval_views=8", "--set", "eval_resolution=128", "--set", "polish_steps=4",
        "--set", "fit_passes=1")
GOOD = ["s0", "s1", "s2", "s3", "s4", "ring"]


def batch(*args, timeout=300, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "batch.py"), *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT, env=env)


def _library(folder: Path) -> Path:
    folder.mkdir()
    for i in range(5):
        write_ply(folder / f"s{i}.ply", *noisy_sphere(320 * (i + 2), seed=i))
    write_ply(folder / "ring.ply", *torus(24, 12))
    (folder / "broken.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n")
    return folder


def _kill_during_a_task(cluster: LocalCluster, out: Path, driver: subprocess.Popen) -> tuple:
    """Waits for the second worker node to run an input's batch.py, then kills that node's
    raylet mid-run; returns (the input's name, its batch.py's pid)."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and driver.poll() is None:
        raylet = cluster.raylet(1)
        runs = {pid: cmd for pid, cmd in cluster.descendants(raylet).items()
                if "batch.py" in cmd and "--result-name" in cmd} if raylet else {}
        for pid, cmd in runs.items():
            name = cmd.split("--result-name ")[1].split()[0]
            if name not in GOOD:
                continue
            time.sleep(1.0)             # well inside its run: bpy alone takes longer
            assert not (out / f"{name}.metrics.json").exists()
            cluster.kill_worker(1)
            return name, pid
        time.sleep(0.1)
    raise AssertionError("the second worker node ran no input")


def _driver(lib: Path, out: Path, cluster: LocalCluster, log: Path) -> subprocess.Popen:
    """batch.py --ray started as a shell's background job starts it: SIGINT ignored (Python
    then installs no handler of its own; batch.py must, or Ctrl-C and kill -INT go unseen)."""
    with open(log, "w") as f:
        return subprocess.Popen([sys.executable, str(ROOT / "batch.py"), "--input", str(lib),
                                 "--output", str(out), *TINY, "--ray", cluster.address],
                                stdout=f, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                                env=cluster.env,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))


def _interrupt_after_one(out: Path, driver: subprocess.Popen) -> None:
    """Ctrl-C as soon as one input's result is complete."""
    deadline = time.monotonic() + 120
    while not list(out.glob("*.metrics.json")) and time.monotonic() < deadline:
        assert driver.poll() is None, driver.communicate()[1]
        time.sleep(0.1)
    driver.send_signal(signal.SIGINT)


@RAY
@BPY
def test_a_cluster_with_a_worker_killed_gives_the_serial_bytes(tmp_path):
    """Interrupted once, resumed with a worker node killed mid-input: the serial bytes."""
    lib = _library(tmp_path / "lib")
    serial, out = tmp_path / "serial", tmp_path / "ray"
    t0 = time.monotonic()
    r = batch("--input", lib, "--output", serial, *TINY)
    assert r.returncode == 1 and "done: 6/7" in r.stdout, r.stdout + r.stderr
    times = {"serial": time.monotonic() - t0}
    with LocalCluster(workers=2, cpus=1) as cluster:
        times["cluster up"] = time.monotonic() - t0 - sum(times.values())
        driver = _driver(lib, out, cluster, tmp_path / "first.log")
        try:
            _interrupt_after_one(out, driver)
            _, err = driver.communicate(timeout=120)
        finally:
            if driver.poll() is None:
                driver.kill()
        assert driver.returncode == 130 and err.strip().splitlines()[-1] == \
            "batch.py: interrupted", err
        complete = {p.name.split(".")[0] for p in out.glob("*.metrics.json")}
        assert complete and not [p.name for p in out.iterdir() if ".partial-" in p.name]
        stamps = {p.name: p.stat().st_mtime_ns for p in out.iterdir()
                  if p.name.split(".")[0] in complete}
        times["interrupted"] = time.monotonic() - t0 - sum(times.values())
        # resumed: the complete results skipped (untouched), a worker node killed mid-input
        log = tmp_path / "second.log"
        driver = _driver(lib, out, cluster, log)
        try:
            killed, pid = _kill_during_a_task(cluster, out, driver)
            _, err = driver.communicate(timeout=300)
        finally:
            if driver.poll() is None:
                driver.kill()
        times["resumed, a node killed"] = time.monotonic() - t0 - sum(times.values())
        text = log.read_text()
        rest = 7 - len(complete)
        assert driver.returncode == 1 and f"done: {rest - 1}/{rest}" in text, text + err
        assert f"{len(complete)} complete before, skipped" in text
        assert all(p.stat().st_mtime_ns == stamps[p.name] for p in out.iterdir()
                   if p.name in stamps)
    times["cluster down"] = time.monotonic() - t0 - sum(times.values())
    # the one broken input fails alone, named on one line
    errors = [line for line in err.splitlines() if line.startswith("batch.py: error:")]
    assert len(errors) == 1 and "broken.ply" in errors[0] and "NaN" in errors[0], err
    assert "Traceback" not in err
    # the killed node's batch.py died with its worker, and its input ran again elsewhere
    assert not Path(f"/proc/{pid}").exists()
    assert killed not in complete and (out / f"{killed}.metrics.json").exists()
    for name in GOOD:
        for suffix in (".bary", ".bin", ".gltf"):
            assert (out / f"{name}{suffix}").read_bytes() == \
                (serial / f"{name}{suffix}").read_bytes(), f"{name}{suffix} differs"
    assert not [p.name for p in out.iterdir() if ".partial-" in p.name]
    assert not list(out.glob("broken*"))
    summary = json.loads((out / "batch-summary.json").read_text())
    status = {Path(r["input"]).name: r["status"] for r in summary["inputs"]}
    assert status == {**{f"{n}.ply": "skipped" if n in complete else "done" for n in GOOD},
                      "broken.ply": "failed"}
    assert summary["run"]["skipped"] == len(complete) and summary["run"]["nodes"] == 2
    assert all(r["node"] and r["seconds"] > 0 for r in summary["inputs"] if r["status"] == "done")
    assert (out / "batch-summary.csv").read_text().count("\n") == 8
    print(", ".join(f"{k} {v:.0f} s" for k, v in times.items()), file=sys.stderr)


@BPY
def test_the_serial_run_resumes_too(tmp_path):
    """--resume without Ray: the complete result is skipped, an incomplete one (files
    without their metrics marker) is done again; without --resume both are refused."""
    lib = tmp_path / "lib"
    lib.mkdir()
    for i in range(2):
        write_ply(lib / f"s{i}.ply", *noisy_sphere(320, seed=i))
    out = tmp_path / "out"
    quick = ("--method", "projection", "--level", "1", "--target-faces", "40",
             "--base-error", "0")
    r = batch("--input", lib, "--output", out, *quick)
    assert r.returncode == 0, r.stdout + r.stderr
    (out / "s1.metrics.json").unlink()            # as if interrupted before its marker
    first = (out / "s0.blend").stat().st_mtime_ns
    r = batch("--input", lib, "--output", out, *quick)
    assert r.returncode == 2 and "--resume" in r.stderr, r.stderr
    r = batch("--input", lib, "--output", out, *quick, "--resume")
    assert r.returncode == 0 and "skipping 1 input(s)" in r.stdout, r.stdout + r.stderr
    assert "done: 1/1" in r.stdout and (out / "s1.metrics.json").exists()
    assert (out / "s0.blend").stat().st_mtime_ns == first
    assert os.path.getsize(out / "s1.bary") > 0
