"""Shared test fixtures: the repository root and tests/ on sys.path, and the real-mesh folder.

The tests are in tests/core (no Blender) and tests/blender (bpy, the add-on's operators,
batch.py); the helpers they share (corpus, shapes, oracles, local_ray) stay here in tests/,
imported by name (``from shapes import torus``) from either folder."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
import torch

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
for _path in (TESTS, ROOT):        # ROOT first: the repository's packages (core, cli, ...)
    if str(_path) not in sys.path:
        sys.path.insert(0, str(_path))

MESHES = Path(os.environ.get("MICROMESH_MESHES", ROOT.parent / "shared" / "meshes"))


CUDA = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
"""Marks a test that runs only where torch sees a CUDA device (never in CI)."""
DEVICES = ["cpu", pytest.param("cuda", marks=[CUDA, pytest.mark.gpu])]
"""``@pytest.mark.parametrize("device", DEVICES)``: the CPU everywhere, CUDA where there is one."""


def mesh_path(name: str) -> Path:
    """Path of a real test mesh in ../shared/meshes; skips the test where it is absent."""
    p = MESHES / name
    if not p.exists():
        pytest.skip(f"real test mesh {name} not found in {MESHES} (../shared/meshes absent)")
    return p


@pytest.fixture(scope="module")
def registered_addon():
    """The add-on registered in the bpy wheel for a module's tests (``pytestmark``), then
    unregistered; skips where bpy is absent."""
    pytest.importorskip("bpy")
    import micromesh_path

    pkg = micromesh_path.ensure_package()
    pkg.register()
    yield pkg
    pkg.unregister()


@pytest.fixture(scope="session")
def package_index(tmp_path_factory):
    """A scratch folder where pip can reach the package index (it fetches a small wheel);
    skips the test where it cannot."""
    import subprocess

    r = subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "-q", "-d",
                        str(tmp_path_factory.mktemp("dl")), "tqdm==4.70.1"],
                       capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        pytest.skip("the package index cannot be reached")
    return tmp_path_factory.mktemp("pip")


# The bpy 4.5 module can deadlock in a C++ static destructor at process exit (its
# "delayed close" file thread, seen with gdb: GlobalState::~GlobalState waiting in
# pthread_cond_destroy) after the tests have passed. Where bpy was imported, end the process
# right after pytest has finished reporting, with pytest's exit status.
def pytest_sessionfinish(session, exitstatus):
    session.config._micromesh_exitstatus = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    if "bpy" in sys.modules and hasattr(config, "_micromesh_exitstatus"):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(config._micromesh_exitstatus)
