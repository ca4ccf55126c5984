"""The same bytes everywhere: one input of 20k faces at the fast preset (``time_limit_s=0``,
so that no run stops early on a slower clock) gives the same ``.bary``, ``.bin`` and
``.gltf`` with ``--threads`` 1, 2 and 4 (where there are more than 2 cores; no more than the
cores), in an environment that gives the BLAS library one
thread (as Ray does for a task of one CPU: ``OMP_NUM_THREADS``) and on a Ray cluster.
(``core.runtime.threads.pin_blas``: the BLAS reductions follow their thread count.)"""
from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

from core.io.ply import write_ply
from core.mesh.primitives import noisy_sphere
from core.runtime.threads import default_threads
from local_ray import LocalCluster
from test_manifest import ROOT

pytestmark = [pytest.mark.slow,             # batch.py runs in processes of their own
              pytest.mark.skipif(importlib.util.find_spec("bpy") is None,
                                 reason="needs the bpy wheel")]

FILES = (".bary", ".bin", ".gltf")


def _batch(src: Path, out: Path, *args: str, env: dict | None = None) -> dict[str, bytes]:
    r = subprocess.run([sys.executable, str(ROOT / "batch.py"), "--input", str(src),
                        "--output", str(out), "--preset", "fast", "--set", "time_limit_s=0",
                        *args], capture_output=True, text=True, timeout=600, cwd=ROOT,
                       env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    return {s: (out / f"{src.stem}{s}").read_bytes() for s in FILES}


def test_the_bytes_do_not_depend_on_threads_or_the_environment(tmp_path):
    v, f = noisy_sphere(20480, amplitude=0.08, seed=3)
    src = tmp_path / "sphere.ply"
    write_ply(src, v, f)
    first = _batch(src, tmp_path / "t1", "--threads", "1")
    # (more threads than cores are as many as cores: 4 only where there are more than 2)
    counts = [n for n in (2, 4) if n == 2 or default_threads() > 2]
    for name, args, env in (
            *((f"--threads {n}", ("--threads", str(n)), None) for n in counts),
            ("one BLAS thread", ("--threads", "2"),
             dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1"))):
        got = _batch(src, tmp_path / name.replace(" ", "_"), *args, env=env)
        for s in FILES:
            assert got[s] == first[s], f"{name}: {s} differs from --threads 1"
    if importlib.util.find_spec("ray") is None:
        pytest.skip("the ray package is not installed (requirements-ray.txt): serial bytes only")
    with LocalCluster(workers=1, cpus=1) as cluster:
        got = _batch(src, tmp_path / "ray", "--ray", cluster.address, env=cluster.env)
    for s in FILES:
        assert got[s] == first[s], f"--ray: {s} differs from the serial run"
