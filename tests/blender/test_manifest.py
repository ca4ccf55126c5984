"""The manifest passes Blender's own validator and builds a zip without tests/bench/CI/docs.

Blender's packager ships inside the ``bpy`` wheel as a standalone script
(``scripts/addons_core/bl_pkg/cli/blender_ext.py``) that runs with plain Python.
"""
from __future__ import annotations

import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def blender_ext_script() -> Path:
    """Path of Blender's packager script inside the installed ``bpy`` wheel (skips if absent)."""
    import importlib.util

    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        pytest.skip("bpy wheel not installed")
    base = Path(list(spec.submodule_search_locations)[0])
    hits = sorted(base.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not hits:
        pytest.skip("bpy wheel has no bl_pkg/cli/blender_ext.py")
    return hits[-1]


def run_blender_ext(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(blender_ext_script()), *args], capture_output=True,
                          text=True, timeout=120)


def build_extension_zip(out_dir: Path) -> Path:
    """Build the extension zip with Blender's packager into ``out_dir``; returns its path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    r = run_blender_ext("build", "--source-dir", str(ROOT), "--output-dir", str(out_dir))
    assert r.returncode == 0, r.stdout + r.stderr
    zips = list(out_dir.glob("micromesh-*.zip"))
    assert len(zips) == 1, r.stdout
    return zips[0]


def test_manifest_fields():
    m = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    assert m["schema_version"] == "1.0.0"
    assert (m["id"], m["version"], m["type"]) == ("micromesh", "0.1.0", "add-on")
    assert m["blender_version_min"] == "4.2.0"
    assert m["license"] == ["SPDX:GPL-3.0-or-later"]
    assert m["permissions"]["files"]
    excluded = m["build"]["paths_exclude_pattern"]
    for p in ("/tests/", "/bench/", "/.ci/", "/docs/", "/.venv/"):
        assert p in excluded


@pytest.mark.slow
def test_validate_source_dir():
    r = run_blender_ext("validate", str(ROOT))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "Success" in r.stdout


@pytest.mark.slow
def test_build_and_validate_zip(tmp_path):
    z = build_extension_zip(tmp_path)
    names = zipfile.ZipFile(z).namelist()
    for needed in ("blender_manifest.toml", "__init__.py", "core/mesh/trimesh.py",
                   "operators/bl_mesh.py", "batch.py", "ui/preferences.py", "ui/panels.py"):
        assert needed in names, needed
    for n in names:
        top = n.split("/")[0]
        assert top not in ("tests", "bench", ".ci", "docs", ".venv", ".git", "out", "dist"), n
        assert "__pycache__" not in n and not n.endswith((".pyc", ".blend")), n
    r = run_blender_ext("validate", str(z))
    assert r.returncode == 0, r.stdout + r.stderr
