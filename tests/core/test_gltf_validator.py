"""Khronos' glTF-Validator reports no errors and no warnings on every exported combination
(informational notes about the NV_ vendor extensions are expected). ``.ci/run`` installs the
validator from the npm registry into ``.ci/npm``; elsewhere the test skips with the reason."""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from core.io.images import HeightCode, png
from core.io.maps_files import base_gltf
from core.io.micromesh_export import write_micromesh
from core.maps import bake_maps
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.micro.levels import balance_levels
from core.mesh.primitives import icosphere

ROOT = Path(__file__).resolve().parents[2]
MODULES = ROOT / ".ci" / "npm" / "node_modules"
SCRIPT = Path(__file__).parents[1] / "tools" / "gltf_validate.js"


def _validator() -> str:
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed (the glTF-Validator runs on Node.js)")
    if not (MODULES / "gltf-validator").is_dir():
        pytest.skip("gltf-validator is not installed: npm install --prefix .ci/npm "
                    "gltf-validator@2.0.0-dev.3.10 (.ci/run does)")
    return node


@pytest.mark.slow
def test_exports_validate_without_errors_or_warnings(tmp_path):
    node = _validator()
    base = TriMesh(*icosphere(2))
    rng = np.random.default_rng(3)
    mm = MicroMesh.flat(base, balance_levels(base, rng.integers(0, 4, base.n_faces)))
    p = mm.micro_vertex_base_positions()
    mm = mm.with_displacements(0.05 * np.sin(7 * p[:, 0]))
    files = []
    for fmt in ("r11", "float"):
        for layout in ("bird", "umajor"):
            for ext in (".gltf", ".glb"):
                f = tmp_path / f"{fmt}_{layout}{ext}"
                write_micromesh(f, mm, value_format=fmt, layout=layout, y_up=ext == ".glb")
                files.append(str(f))
    maps = bake_maps(mm, 64)              # the maps path: base + UVs + height and normal maps
    code = HeightCode.spanning(maps.height)
    (tmp_path / "h.png").write_bytes(png(code.values(maps.height)))
    (tmp_path / "n.png").write_bytes(png(maps.normal))
    (tmp_path / "c.png").write_bytes(png(np.full((64, 64, 4), 0.5), bits=8))
    (tmp_path / "mr.png").write_bytes(png(np.full((64, 64, 3), 0.5), bits=8))
    (tmp_path / "e.png").write_bytes(png(np.full((64, 64, 3), 0.2), bits=8))
    for name, textures in (("base", {"baseColorTexture": "c.png"}),
                           ("textured", {"baseColorTexture": "c.png", "emissiveTexture": "e.png",
                                         "metallicRoughnessTexture": "mr.png"})):
        for path, data in base_gltf(tmp_path / f"{name}.gltf", mm, maps, "n.png", "h.png",
                                    code, textures=textures):
            path.write_bytes(data)
        files.append(str(tmp_path / f"{name}.gltf"))
    r = subprocess.run([node, str(SCRIPT), *files], capture_output=True, text=True,
                       timeout=120, env={"NODE_PATH": str(MODULES)})
    assert r.returncode == 0, r.stderr
    reports = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(reports) == len(files)
    for rep in reports:
        assert rep["errors"] == 0 and rep["warnings"] == 0, rep
