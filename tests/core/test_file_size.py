"""The bytes micro-mesh files take on disk: ours as the exporter writes them, micromesh-tools'
as its files hold them, and the default budget that counts them."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from core.construct.state import ESTIMATE_MARGIN, budget_cost
from core.io.file_size import micromesh_file_bytes, mmt_file_bytes
from core.io.micromesh_export import write_micromesh
from core.io.micromesh_import import read_micromesh
from core.lod.expansion import expansion_bytes, expansion_levels, nominal_expansion_bytes
from core.mesh.trimesh import TriMesh
from core.micro.levels import balance_levels
from core.micro.micromesh import MicroMesh
from core.mesh.primitives import icosphere
from core.settings.fields import preset

from test_expansion import octahedron
from test_micromesh_files import BASELINES


def _micromesh(base: TriMesh, seed: int, max_level: int) -> MicroMesh:
    rng = np.random.default_rng(seed)
    mm = MicroMesh.flat(base, balance_levels(base, rng.integers(0, max_level + 1, base.n_faces)))
    p = mm.micro_vertex_base_positions()
    return mm.with_displacements(0.05 * np.sin(5 * p[:, 0]) * np.cos(3 * p[:, 1]))


def _on_disk(path) -> int:
    return path.with_suffix(".bin").stat().st_size + path.with_suffix(".bary").stat().st_size


@pytest.mark.parametrize("subdivisions, drop, max_level, fmt", [
    (1, 0, 5, "r11"), (1, 1, 4, "float"), (2, 3, 3, "r11"), (2, 2, 2, "float")])
def test_the_count_is_the_bytes_the_exporter_writes(tmp_path, subdivisions, drop, max_level,
                                                     fmt):
    """Face counts of every remainder by 4 (the u8 flags and u16 indices padded; faces
    dropped leave an open surface), every level up to 5, both value formats."""
    v, f = icosphere(subdivisions)
    mm = _micromesh(TriMesh(v, f[:len(f) - drop]), subdivisions, max_level)
    write_micromesh(tmp_path / "m.gltf", mm, value_format=fmt)
    size = micromesh_file_bytes(mm.levels, mm.base.n_vertices, fmt)
    assert size["bin"] == (tmp_path / "m.bin").stat().st_size
    assert size["bary"] == (tmp_path / "m.bary").stat().st_size
    assert size["total"] == _on_disk(tmp_path / "m.gltf")


@pytest.mark.parametrize("n_vertices, width", [(65535, 2), (65536, 4)])
def test_indices_are_u16_while_they_fit(tmp_path, n_vertices, width):
    """glTF reserves 65535 in u16 indices: up to 65,535 vertices (indices 0..65534) they are
    u16, from 65,536 u32; the count follows, and the file reads back."""
    tri = TriMesh(*icosphere(1))
    far = np.full((n_vertices - tri.n_vertices, 3), 5.0) + np.arange(n_vertices - 12)[:, None]
    base = TriMesh(np.vstack([far, tri.vertices]), tri.faces + len(far))   # index 65534 / 65535
    mm = _micromesh(base, 0, 2)
    write_micromesh(tmp_path / "m.gltf", mm)
    doc = json.loads((tmp_path / "m.gltf").read_text())
    prim = doc["meshes"][0]["primitives"][0]
    assert doc["accessors"][prim["indices"]]["componentType"] == {2: 5123, 4: 5125}[width]
    assert micromesh_file_bytes(mm.levels, n_vertices)["total"] == _on_disk(tmp_path / "m.gltf")
    np.testing.assert_array_equal(read_micromesh(tmp_path / "m.gltf").faces, base.faces)


def test_each_datum_is_written_once(tmp_path):
    """Directions and flags as accessors only, no direction bounds (folded in), no level view
    (the .bary's triangle records hold the levels), four .bary properties."""
    from core.io import bary as B
    mm = _micromesh(TriMesh(*icosphere(1)), 3, 3)
    write_micromesh(tmp_path / "m.gltf", mm)
    doc = json.loads((tmp_path / "m.gltf").read_text())
    ext = doc["meshes"][0]["primitives"][0]["extensions"]
    assert list(ext) == ["NV_displacement_micromap"]
    assert set(ext["NV_displacement_micromap"]) == {"micromap", "directions", "primitiveFlags"}
    assert sorted(v["name"] for v in doc["bufferViews"]) == sorted(
        ["indices", "positions", "normals", "directions", "primitive_flags"])
    bf = B.decode((tmp_path / "m.bary").read_bytes())
    assert bf.directions is None and bf.direction_bounds is None and bf.triangle_flags is None
    assert bf.minmax is not None and bf.extra == {}


@pytest.mark.skipif(not BASELINES, reason="../shared/baselines (micromesh-tools' outputs) absent")
@pytest.mark.parametrize("path", BASELINES, ids=lambda p: p.parent.name)
def test_micromesh_tools_files_take_what_the_count_says(path):
    f = read_micromesh(path)
    on_disk = path.with_suffix(".bin").stat().st_size + path.with_suffix(".bary").stat().st_size
    assert mmt_file_bytes(f.levels, len(f.positions)) == on_disk


def test_nominal_bytes_are_those_of_the_base_the_decimation_aims_at():
    """An octahedron (8 equal faces, 6 = 8 / 2 + 2 vertices) as the base of a 256-face input
    (8 = 256 / 32): all its faces at level 3 (2 × 256 micro-triangles), the bytes the estimate
    from the input's face count gives."""
    base = octahedron()
    assert expansion_levels(base, 256, 2.0).tolist() == [3] * 8
    assert nominal_expansion_bytes(256, 2.0) == expansion_bytes(base, 256, 2.0) \
        == mmt_file_bytes(np.full(8, 3), 6)
    assert nominal_expansion_bytes(256, 0.0) == 0
    assert nominal_expansion_bytes(10, 2.0) > 0                         # one face at least


def test_the_default_budget_is_micromesh_tools_files_and_counts_ours():
    """On the base at hand its files' bytes for its uniform tessellation; on a base much
    coarser than its decimation's aim, what that aim would take (the input's face count
    alone); the cost is our files' bytes."""
    base = TriMesh(*icosphere(2))                      # 80 faces, twice the aim's 1280 / 32
    cost, budget, unit = budget_cost(preset("default"), base, 16 * base.n_faces)
    assert unit == "disk_bytes"
    theirs = expansion_bytes(base, 16 * base.n_faces, 2.0)
    assert budget == math.floor(ESTIMATE_MARGIN * theirs) < theirs
    assert budget > nominal_expansion_bytes(16 * base.n_faces, 2.0)
    lv = expansion_levels(base, 16 * base.n_faces, 2.0)
    assert cost(lv) == micromesh_file_bytes(lv, base.n_vertices)["total"] < budget
    coarse = octahedron()
    _, floor, _ = budget_cost(preset("default"), coarse, 100 * 32 * coarse.n_faces)
    nominal = nominal_expansion_bytes(100 * 32 * coarse.n_faces, 2.0)
    assert floor == math.floor(ESTIMATE_MARGIN * nominal) \
        > expansion_bytes(coarse, 100 * 32 * coarse.n_faces, 2.0)
    cost_b, budget_b, unit_b = budget_cost(preset("default", budget_bytes=5000), base, 1)
    assert (budget_b, unit_b) == (5000, "bytes") and cost_b(lv) == cost(lv)
