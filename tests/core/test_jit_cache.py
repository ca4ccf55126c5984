"""The kernels' on-disk cache (core/runtime/jit.py, core/construct/warm.py): an entry is served again on the
same CPU, never to another CPU (numba keys entries by target CPU and features), and is_warm
says which of the two it is. Each case runs in a fresh process with its own cache folder."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = r"""
import sys
sys.path.insert(0, sys.argv[1])
from numba.core import event
compiled = []
class Rec(event.Listener):
    def on_start(self, ev): pass
    def on_end(self, ev): compiled.append(ev.data["dispatcher"].py_func.__qualname__)
event.register("numba:compile", Rec())
import numpy as np
from core.render.normals import _face_normals
from core.construct import warm
from numba import typeof
verts = np.random.default_rng(0).random((4, 3)).astype(np.float32)
faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
fn = np.zeros((2, 3), np.float32)
args = (verts, faces, fn, 0, 2)
listed = [{"module": "render.normals", "name": "_face_normals",
           "signature": repr(tuple(typeof(a) for a in args))}]
before = warm.is_warm(listed)
_face_normals(*args)
print("warm_before", before, "compiled", compiled.count("_face_normals"),
      "warm_after", warm.is_warm(listed))
"""


def _run(cache: Path, cpu: str | None = None) -> str:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    env.pop("NUMBA_CPU_NAME", None)
    if cpu:
        env["NUMBA_CPU_NAME"] = cpu
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(ROOT)], capture_output=True, text=True,
                       env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip().splitlines()[-1]


@pytest.mark.slow
def test_cache_serves_this_cpu_and_never_another(tmp_path):
    assert _run(tmp_path) == "warm_before False compiled 1 warm_after True"
    assert _run(tmp_path) == "warm_before True compiled 0 warm_after True"     # from the cache
    # Another CPU (numba's generic x86-64 target stands in for it): not served, compiled anew
    assert _run(tmp_path, "generic") == "warm_before False compiled 1 warm_after True"
    assert _run(tmp_path) == "warm_before True compiled 0 warm_after True"     # both kept


@pytest.mark.slow
def test_warm_command_imports_the_package_under_the_callers_name(tmp_path):
    """warm.command loads the checkout under another import name (as Blender names the
    extension) in a process of its own; asked only whether the kernels are cached, it answers
    for that name (an empty cache: no)."""
    from core.construct import warm

    cmd = warm.command(str(ROOT), "bl_ext.test_repo.micromesh", [], action="is_warm")
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600,
                       env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)})
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "warm: kernels cached: False"


def test_entries_of_earlier_sources_are_pruned(tmp_path):
    """prune_stale removes cache entries whose source digest is not this source's and keeps
    this source's (any import name) and files that are not kernel entries."""
    from core.render import normals
    from core.runtime import jit

    now = jit.source_digest()
    old = "0123456789" if now != "0123456789" else "9876543210"
    names = {f"core.{old}.closest._build-63.py311.1.nbc": False,
             f"core.render.{old}.antialias.pair_codes-157.py311.nbi": False,
             f"core.{now}.closest._build-63.py311.1.nbc": True,
             f"micromesh.core.{now}.closest._build-63.py311.nbi": True,
             "notes.txt": True}
    for n in names:
        (tmp_path / n).write_text("x")
    assert jit.prune_stale([tmp_path, tmp_path / "absent"]) == 2
    assert {p.name for p in tmp_path.iterdir()} == {n for n, keep in names.items() if keep}
    assert normals._face_normals._cache._cache_path in jit.cache_folders()
