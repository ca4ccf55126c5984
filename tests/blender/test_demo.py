"""The README's demo: ``python batch.py`` with no --input builds a procedural mesh with bpy,
decimates it into a base (``core.base``), bakes a micro-mesh and saves a .blend."""
from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

bpy = pytest.importorskip("bpy")

from test_manifest import ROOT  # noqa: E402

pytestmark = pytest.mark.slow     # batch.py in a process of its own


def test_demo_projection(tmp_path):
    r = subprocess.run([sys.executable, str(ROOT / "batch.py"), "--output", str(tmp_path),
                        "--method", "projection", "--level", "2", "--demo-subdivisions", "6"],
                       capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode == 0, r.stdout + r.stderr
    line = [ln for ln in r.stdout.splitlines() if "demo_rock_micromesh:" in ln][-1]
    found = re.search(r"reference 20480 triangles, base (\d+) triangles, \d+ micro-vertices, "
                      r"(\d+) micro-triangles, shell volume [0-9.]+ \(unit sphere\), projection, "
                      r"[0-9.]+ s", line)
    assert found, line
    base_faces, micro = int(found.group(1)), int(found.group(2))
    m = json.loads((tmp_path / "demo_rock.metrics.json").read_text())["metrics"]
    assert m["reference_faces"] == 20480 and m["micro_triangles"] == micro == 16 * base_faces
    assert 640 <= base_faces < 20480 / 2 and m["base"]["topology_base"]["genus"] == 0
    assert 0 < m["shell_volume"] < 1.0
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "demo_rock.blend"))
    try:
        src = bpy.data.objects["demo_rock"]
        res = bpy.data.objects["demo_rock_micromesh"]
        assert len(src.modifiers) == 0 and len(src.data.polygons) == 20480  # a real mesh
        assert res.type == "MESH" and len(res.data.polygons) == micro
        assert res.get("micromesh_data") is not None
        # The procedural source is not a sphere: the textures displaced it.
        import numpy as np

        v = np.empty(3 * len(src.data.vertices))
        src.data.vertices.foreach_get("co", v)
        r_ = np.linalg.norm(v.reshape(-1, 3), axis=1)
        assert r_.std() > 0.02
    finally:
        bpy.ops.wm.read_factory_settings(use_empty=True)
