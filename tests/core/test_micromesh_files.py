"""Micro-mesh files: .bary + glTF/GLB written and read back, the bit layout by hand, the files
micromesh-tools wrote, and malformed input refused with the reader's own error."""
from __future__ import annotations

import json
import struct
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from core.micro.bounds import baked, tight_bounds, unit_bounds
from core.io import bary as B
from core.io.bary_values import decode_values, encode_values
from core.io.gltf import Document
from core.io.micromesh_export import (ExportError, decoded_positions, stored_values,
                                      write_micromesh)
from core.io.micromesh_import import MicromeshFileError, read_micromesh
from core.mesh.trimesh import TriMesh
from core.micro.metrics import mmt_formula_bytes
from core.micro.micromesh import MicroMesh
from core.micro.levels import balance_levels, edge_flags
from core.micro.topology import bird_index
from core.mesh.primitives import icosphere

SHARED = Path(__file__).resolve().parents[3] / "shared"


def _micromesh(seed: int = 0, max_level: int = 4) -> MicroMesh:
    base = TriMesh(*icosphere(1))
    rng = np.random.default_rng(seed)
    mm = MicroMesh.flat(base, balance_levels(base, rng.integers(0, max_level, base.n_faces)))
    p = mm.micro_vertex_base_positions()
    return mm.with_displacements(0.05 * np.sin(5 * p[:, 0]) * np.cos(3 * p[:, 1]))


@pytest.fixture(scope="module")
def mm() -> MicroMesh:
    return _micromesh()


@pytest.mark.parametrize("fmt", ["r11", "float"])
@pytest.mark.parametrize("layout", ["bird", "umajor"])
@pytest.mark.parametrize("suffix", [".gltf", ".glb"])
def test_round_trip(tmp_path, mm, fmt, layout, suffix):
    b = tight_bounds(mm)
    rep = write_micromesh(tmp_path / f"m{suffix}", mm, b, value_format=fmt, layout=layout)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == (["m.glb"] if suffix == ".glb" else ["m.bary", "m.bin", "m.gltf"])
    assert rep.bytes == sum(p.stat().st_size for p in tmp_path.iterdir())
    f = read_micromesh(tmp_path / f"m{suffix}")
    assert f.warnings == []
    np.testing.assert_array_equal(f.faces, mm.base.faces)
    np.testing.assert_array_equal(f.levels, mm.levels)
    np.testing.assert_array_equal(f.flags, edge_flags(mm.base, mm.levels))
    folded = baked(mm, b)                   # the bounds are folded into the file's arrays
    np.testing.assert_array_equal(f.positions, folded.base.vertices.astype(np.float32))
    np.testing.assert_array_equal(f.directions, folded.directions.astype(np.float32))
    assert (f.bias == 0).all() and (f.scale == 1).all()
    values = stored_values(mm, b, fmt)
    _, per_face = mm.with_displacements(values).face_values("umajor")
    np.testing.assert_array_equal(f.values.astype(np.float32), per_face.astype(np.float32))
    back = f.micromesh().micro_vertex_positions()
    np.testing.assert_allclose(back, decoded_positions(mm, b, values), atol=1e-6)


def test_quantization_error_is_reported(tmp_path, mm):
    rep = write_micromesh(tmp_path / "m.gltf", mm)
    assert 0 < rep.quantization_rms <= rep.quantization_max < 0.01


def test_packed_11_bit_layout_by_hand():
    # one level-0 triangle (3 values) and one level-1 triangle (6 values)
    q = np.array([1, 2, 2047, 5, 0, 1024, 7, 2046, 3])
    payload, offsets, count, size = encode_values(
        B.R11_UNORM_PACKED_ALIGN32, np.array([0, 1]), np.array([0, 3, 9]), q / 2047.0)
    w0 = 1 | (2 << 11) | ((2047 & 0x3FF) << 22)   # value 2 straddles the word boundary
    w1 = 2047 >> 10
    w2 = 5 | (0 << 11) | ((1024 & 0x3FF) << 22)
    w3 = (1024 >> 10) | (7 << 1) | (2046 << 12) | ((3 & 0x1FF) << 23)
    w4 = 3 >> 9
    assert list(offsets) == [0, 8] and size == 1 and count == 20
    assert struct.unpack("<5I", payload) == (w0, w1, w2, w3, w4)


def test_bird_curve_payload_order_level2():
    # values = the u-major index: the bird-curve payload lists them in bird order
    base = TriMesh(np.eye(3), np.array([[0, 1, 2]]))
    mm = MicroMesh.flat(base, [2])
    ptr, _ = mm.face_values("umajor")
    umajor = np.arange(15) / 14.0
    payload, _, _, _ = encode_values(B.R32_SFLOAT, np.array([2]), ptr, umajor[np.argsort(
        bird_index(2))])
    stored = np.frombuffer(payload, "<f4") * 14
    rows = [[0, 8, 5, 11, 1], [6, 7, 9, 10], [3, 14, 4], [12, 13], [2]]  # the format note
    got = np.empty(15, int)
    got[np.rint(stored).astype(int)] = np.arange(15)               # u-major → bird position
    u_major_rows = [[got[j] for j in r] for r in [[0, 5, 9, 12, 14], [1, 6, 10, 13], [2, 7, 11],
                                                 [3, 8], [4]]]
    assert u_major_rows == rows


def test_export_refuses_bad_options(tmp_path, mm):
    with pytest.raises(ExportError, match="gltf or .glb"):
        write_micromesh(tmp_path / "m.obj", mm)
    with pytest.raises(ExportError, match="value format"):
        write_micromesh(tmp_path / "m.gltf", mm, value_format="r12")
    assert list(tmp_path.iterdir()) == []


def test_y_up_rotates_positions_and_directions(tmp_path, mm):
    write_micromesh(tmp_path / "m.gltf", mm, y_up=True)
    f = read_micromesh(tmp_path / "m.gltf")
    v = baked(mm, tight_bounds(mm)).base.vertices
    np.testing.assert_allclose(f.positions, np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1), atol=1e-6)


@pytest.mark.parametrize("suffix", [".gltf", ".glb"])
def test_far_from_the_origin_the_file_keeps_the_detail(tmp_path, mm, suffix):
    """At 1e6 float32 positions would be 0.06 apart: the file holds them about a node's
    translation, and reads back in place to float32's step at the object's size; near the
    origin there is no translation."""
    offset = np.array([1e6, -1e6, 1e6])
    far = MicroMesh(mm.base.with_vertices(mm.base.vertices + offset), mm.directions, mm.levels,
                    mm.displacements)
    write_micromesh(tmp_path / f"far{suffix}", far, value_format="float")
    write_micromesh(tmp_path / f"near{suffix}", mm, value_format="float")
    f, near = read_micromesh(tmp_path / f"far{suffix}"), read_micromesh(tmp_path / f"near{suffix}")
    diag = mm.base.bbox_diagonal
    held = baked(far, tight_bounds(far)).base.vertices      # the bounds folded in
    assert np.abs(f.positions - held).max() < 1e-6 * diag
    back, back_near = (x.micromesh().micro_vertex_positions() for x in (f, near))
    assert np.abs(back - offset - back_near).max() < 1e-6 * diag     # as the file at the origin
    assert "translation" not in Document(tmp_path / f"near{suffix}").doc["nodes"][0]


def test_decode_values_refuses_runs_past_the_end(mm):
    bf = B.decode(B.encode(_bary(mm)))
    bf.triangles["offset"][-1] += 4096
    with pytest.raises(B.BaryError, match="past the end"):
        decode_values(bf)
    bf = B.decode(B.encode(_bary(mm)))
    bf.triangles["level"][0] = 16
    with pytest.raises(B.BaryError, match="over 15"):
        decode_values(bf)


def _bary(mm):
    from core.io.micromesh_export import to_bary
    return to_bary(baked(mm, tight_bounds(mm)))


@pytest.fixture(scope="module")
def good_files(tmp_path_factory, mm):
    d = tmp_path_factory.mktemp("good")
    write_micromesh(d / "a.gltf", _micromesh(1, 3))
    write_micromesh(d / "b.glb", _micromesh(2, 3), value_format="float", layout="umajor")
    return {p.name: p.read_bytes() for p in d.iterdir()}


def _read_mutated(tmp_path, files: dict, name: str, data: bytes, entry: str) -> None:
    for n, b in files.items():
        (tmp_path / n).write_bytes(data if n == name else b)
    t = time.perf_counter()
    try:
        f = read_micromesh(tmp_path / entry)
        f.micromesh()
    except MicromeshFileError:
        pass
    # A guard against a hang or a giant allocation from a corrupted count, not a speed target:
    # the first read may compile the reader's kernels on a fresh cache.
    assert time.perf_counter() - t < 10.0


@settings(max_examples=60, deadline=None)
@given(which=st.sampled_from(["a.bary", "a.gltf", "a.bin", "b.glb"]),
       cut=st.floats(0, 1), flips=st.lists(st.tuples(st.floats(0, 1), st.integers(0, 7)),
                                           max_size=8))
def test_fuzzed_files_raise_only_the_readers_error(tmp_path_factory, good_files, which, cut,
                                                    flips):
    data = bytearray(good_files[which])
    for pos, bit in flips:
        data[int(pos * (len(data) - 1))] ^= 1 << bit
    data = bytes(data[:max(1, int(cut * len(data)) if cut < 0.9 else len(data))])
    entry = "b.glb" if which == "b.glb" else "a.gltf"
    _read_mutated(tmp_path_factory.mktemp("fuzz"), good_files, which, data, entry)


@settings(max_examples=40, deadline=None)
@given(header=st.binary(min_size=40, max_size=400))
def test_random_bary_headers_are_refused(tmp_path_factory, good_files, header):
    data = B.MAGIC + header[16:] if header[:1] == b"\0" else header
    _read_mutated(tmp_path_factory.mktemp("hdr"), good_files, "a.bary", data, "a.gltf")


def test_malformed_cases_name_the_problem(tmp_path, good_files):
    for n, b in good_files.items():
        (tmp_path / n).write_bytes(b)
    bary = good_files["a.bary"]
    cases = {
        b"not a bary file at all, really not one" + bytes(10): "bad magic",
        bary[:-8]: "header says",
        bary[:16] + struct.pack("<Q", len(bary)) + struct.pack("<2Q", 10**9, 64) + bary[40:]:
            "property table",
    }
    for data, msg in cases.items():
        (tmp_path / "a.bary").write_bytes(data)
        with pytest.raises(MicromeshFileError, match=msg):
            read_micromesh(tmp_path / "a.gltf")
    (tmp_path / "a.bary").unlink()
    with pytest.raises(MicromeshFileError, match="missing"):
        read_micromesh(tmp_path / "a.gltf")
    doc = json.loads(good_files["a.gltf"])
    del doc["meshes"][0]["primitives"][0]["extensions"]
    (tmp_path / "a.gltf").write_text(json.dumps(doc))
    with pytest.raises(MicromeshFileError, match="no primitive"):
        read_micromesh(tmp_path / "a.gltf")


BASELINES = sorted((SHARED / "baselines").glob("*/out_*.gltf"))


@pytest.mark.skipif(not BASELINES, reason="../shared/baselines (micromesh-tools' outputs) absent")
@pytest.mark.parametrize("path", BASELINES, ids=lambda p: p.parent.name)
def test_micromesh_tools_files_import(path):
    stats = dict(line.split(maxsplit=1) for line in
                 (path.parent / f"stats_{path.stem}.stats").read_text().splitlines()
                 if " " in line)
    f = read_micromesh(path)
    mm = f.micromesh()
    # beast_65k's file stores different values at a few vertices where two sheets of its
    # non-manifold base meet: the only warning allowed, for at most 0.1 % of the vertices
    for w in f.warnings:
        assert "shared micro-vertices" in w and int(w.split()[0]) <= mm.n_vertices // 1000, w
    assert mm.topology.n_triangles == int(stats["micro_fn"])
    assert len(f.levels) == int(stats["base_fn"])
    assert mmt_formula_bytes(f.levels, len(f.positions)) == int(stats["out_size"])


def test_a_baked_micromesh_is_what_its_file_holds(tmp_path, mm):
    """Per-vertex bounds cannot say every position of a micro-mesh; folded into the base and
    the directions (what constructions return) they can: float files exactly, 11-bit files up
    to the rounding of the values."""
    b = tight_bounds(mm)
    assert write_micromesh(tmp_path / "a.gltf", mm, b, value_format="float").quantization_max \
        > 1e-4
    folded = baked(mm, b)
    unit = unit_bounds(mm.base.n_vertices)
    exact = write_micromesh(tmp_path / "b.gltf", folded, unit, value_format="float")
    assert exact.quantization_max < 1e-6
    back = read_micromesh(tmp_path / "b.gltf").micromesh().micro_vertex_positions()
    np.testing.assert_allclose(back, folded.micro_vertex_positions(), atol=1e-6)
    r11 = write_micromesh(tmp_path / "c.glb", folded, unit)
    step = np.linalg.norm(folded.directions, axis=1).max() / 2047 / mm.base.bbox_diagonal
    assert r11.quantization_max <= step
