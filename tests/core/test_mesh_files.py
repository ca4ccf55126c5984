"""PLY/OBJ/STL reading and binary PLY writing."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from conftest import MESHES, mesh_path
from core.io.mesh_files import MeshFileError, read_mesh, write_ply

CUBE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                   [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=np.float64)
CUBE_QUADS = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]


def _fan(quads):
    return np.array([[q[0], q[i], q[i + 1]] for q in quads for i in range(1, len(q) - 1)])


def test_round_trip_double_and_float(tmp_path):
    rng = np.random.default_rng(0)
    v = rng.normal(size=(50, 3))
    f = rng.integers(0, 50, size=(80, 3))
    p = tmp_path / "m.ply"
    write_ply(p, v, f, double=True)
    m = read_mesh(p)
    assert np.array_equal(m.vertices, v) and np.array_equal(m.faces, f)
    write_ply(p, v, f)
    m = read_mesh(p)
    assert np.allclose(m.vertices, v, atol=1e-6) and np.array_equal(m.faces, f)
    assert [x.name for x in tmp_path.iterdir()] == ["m.ply"]  # no temp file left behind


def test_ascii_ply_with_polygons_and_extra_properties(tmp_path):
    lines = ["ply", "format ascii 1.0", "comment test", "element vertex 8",
             "property float x", "property float y", "property float z", "property uchar red",
             "element face 6", "property uchar flags", "property list uchar int vertex_indices",
             "property float quality", "element edge 1", "property int a", "property int b",
             "end_header"]
    lines += [f"{x} {y} {z} 255" for x, y, z in CUBE_V]
    lines += [f"7 4 {' '.join(map(str, q))} 0.5" for q in CUBE_QUADS]
    lines += ["0 1"]
    p = tmp_path / "cube.ply"
    p.write_text("\n".join(lines) + "\n")
    m = read_mesh(p)
    assert np.array_equal(m.vertices, CUBE_V)
    assert np.array_equal(m.faces, _fan(CUBE_QUADS))
    assert m.is_closed_manifold


def test_binary_ply_mixed_polygons_double_uint_and_skipped_elements(tmp_path):
    header = ("ply\nformat binary_little_endian 1.0\nelement material 2\nproperty list uchar float rgb\n"
              "element vertex 8\nproperty double x\nproperty double y\nproperty double z\n"
              "property float nx\nelement face 7\nproperty list uchar uint vertex_indices\n"
              "property short tag\nend_header\n")
    body = b""
    for n in (3, 1):
        body += np.uint8(n).tobytes() + np.arange(n, dtype="<f4").tobytes()
    vrec = np.zeros(8, dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("nx", "<f4")])
    vrec["x"], vrec["y"], vrec["z"] = CUBE_V.T
    body += vrec.tobytes()
    q1 = CUBE_QUADS[1]
    polys = [CUBE_QUADS[0], q1[:3], [q1[0], q1[2], q1[3]]] + CUBE_QUADS[2:]
    for q in polys:
        body += np.uint8(len(q)).tobytes() + np.array(q, "<u4").tobytes() + np.int16(-1).tobytes()
    p = tmp_path / "mixed.ply"
    p.write_bytes(header.encode() + body)
    m = read_mesh(p)
    assert np.array_equal(m.vertices, CUBE_V)
    assert np.array_equal(m.faces, _fan(polys))
    assert m.n_faces == 12 and m.is_closed_manifold


def test_big_endian_ply(tmp_path):
    header = ("ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n"
              "property float y\nproperty float z\nelement face 1\n"
              "property list uchar int vertex_indices\nend_header\n")
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0]], ">f4")
    body = v.tobytes() + np.uint8(3).tobytes() + np.array([0, 1, 2], ">i4").tobytes()
    p = tmp_path / "be.ply"
    p.write_bytes(header.encode() + body)
    m = read_mesh(p)
    assert np.array_equal(m.vertices, v.astype(np.float64)) and m.faces.tolist() == [[0, 1, 2]]


def test_obj_negative_indices_polygons_and_texcoords(tmp_path):
    txt = ["# cube", "o cube"] + [f"v {x} {y} {z}" for x, y, z in CUBE_V] + ["vt 0 0", "vn 0 0 1"]
    for q in CUBE_QUADS[:3]:
        txt.append("f " + " ".join(f"{i + 1}/1/1" for i in q))
    for q in CUBE_QUADS[3:]:
        txt.append("f " + " ".join(str(i - 8) for i in q))  # negative: relative to 8 read so far
    p = tmp_path / "cube.obj"
    p.write_text("\n".join(txt) + "\n")
    m = read_mesh(p)
    assert np.array_equal(m.vertices, CUBE_V)
    assert np.array_equal(m.faces, _fan(CUBE_QUADS))


@pytest.mark.parametrize("content,name", [
    (b"not a mesh at all", "a.ply"),
    (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\x00\x00",
     "trunc.ply"),
    (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty flt x\nend_header\n", "t.ply"),
    (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
     b"element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 1 2\n", "oob.ply"),
    (b"v 0 0 0\nv 1 0 0\nf 1 2 x\n", "bad.obj"),
    (b"v 0 0 0\n", "nofaces.obj"),
    (b"solid x\n", "a.stl"),
])
def test_malformed_files_raise(tmp_path, content, name):
    p = tmp_path / name
    p.write_bytes(content)
    with pytest.raises(MeshFileError):
        read_mesh(p)


CUBE_TRIS = CUBE_V[_fan(CUBE_QUADS)]          # (12, 3, 3): the cube's triangles, corners


def _stl_binary(tris: np.ndarray, header: bytes = b"solid cube (binary, as many exporters)"
                ) -> bytes:
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tris
    return header.ljust(80, b" ") + np.uint32(len(tris)).tobytes() + rec.tobytes()


def _stl_ascii(tris: np.ndarray, name: str = "cube", newline: str = "\n") -> str:
    lines = [f"solid {name}"]
    for t in tris:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += [f"      vertex {x:.9g} {y:.9g} {z:.9g}" for x, y, z in t]
        lines += ["    endloop", "  endfacet"]
    return newline.join(lines + [f"endsolid {name}", ""])


@pytest.mark.parametrize("kind", ["binary", "ascii", "ascii_crlf_two_solids"])
def test_stl_is_read_as_the_triangle_soup_it_lists(tmp_path, kind):
    """A binary STL whose header begins with "solid" is still binary (told by its size);
    ASCII with CRLF line ends and two solids in one file; every triangle keeps its three
    vertices as listed (the construction welds them, not the reader)."""
    p = tmp_path / "cube.stl"
    if kind == "binary":
        p.write_bytes(_stl_binary(CUBE_TRIS))
    elif kind == "ascii":
        p.write_text(_stl_ascii(CUBE_TRIS))
    else:
        p.write_text(_stl_ascii(CUBE_TRIS[:5], "a", "\r\n")
                     + _stl_ascii(CUBE_TRIS[5:], "b", "\r\n"))
    m = read_mesh(p)
    assert np.array_equal(m.vertices, CUBE_TRIS.reshape(-1, 3))
    assert np.array_equal(m.faces, np.arange(36).reshape(12, 3))


@pytest.mark.parametrize("make, reason", [
    (lambda: _stl_binary(CUBE_TRIS)[:-7], "truncated binary STL: 12 triangles take 684 bytes, "
                                          "the file has 677"),
    (lambda: _stl_binary(CUBE_TRIS) + b"\0\0", "2 bytes more than its 12 triangles"),
    (lambda: _stl_binary(CUBE_TRIS[:0]), "no triangles"),
    (lambda: b"solid empty\nendsolid empty\n", "no triangles"),
    (lambda: b"sol", "not an STL file"),
    (lambda: _stl_binary(np.where(np.arange(12)[:, None, None] < 3, np.inf, CUBE_TRIS)),
     "3 of 12 triangles have NaN or infinite coordinates"),
    (lambda: _stl_ascii(CUBE_TRIS).replace("vertex 1 0 0", "vertex 1 nan 0", 1).encode(),
     "1 of 12 triangles have NaN or infinite"),
    (lambda: _stl_ascii(CUBE_TRIS).encode()[:-60], "truncated ASCII STL"),
    (lambda: _stl_ascii(CUBE_TRIS).replace("      vertex 1 1 0\n", "", 1).encode(),
     "not a valid ASCII STL at line 6 ('endloop')"),
    (lambda: _stl_ascii(CUBE_TRIS).replace("vertex 1 0 0", "vertex 1 zero 0", 1).encode(),
     "bad number"),
    (lambda: _stl_ascii(CUBE_TRIS).replace("vertex 1 0 0", "vertex 1 0", 1).encode(),
     "without three numbers"),
])
def test_a_bad_stl_is_refused_naming_why(tmp_path, make, reason):
    p = tmp_path / "bad.stl"
    p.write_bytes(make())
    with pytest.raises(MeshFileError) as e:
        read_mesh(p)
    assert reason in str(e.value) and "\n" not in str(e.value)


def test_missing_file_raises(tmp_path):
    with pytest.raises(MeshFileError, match="no such file"):
        read_mesh(tmp_path / "nope.ply")


def _manifest():
    p = MESHES / "MANIFEST.csv"
    if not p.exists():
        return []
    with open(p) as fh:
        return [(r["file"], int(r["vertices"]), int(r["faces"])) for r in csv.DictReader(fh)]


@pytest.mark.meshes
@pytest.mark.parametrize("name,nv,nf", _manifest() or [("igea_269k.ply", 134345, 268686)])
def test_real_meshes_match_manifest(name, nv, nf):
    m = read_mesh(mesh_path(name))
    assert (m.n_vertices, m.n_faces) == (nv, nf)
