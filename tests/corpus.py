"""Messy inputs made from a clean mesh, as users hand them over: triangle soups, STL, USD,
far from the origin, degenerate faces, T-junctions, holes, non-manifold fins, hundreds of
parts, non-finite values and broken files. Used by ``tests/blender/test_messy_inputs.py`` and
``bench/messy_bench.py``.

Each :class:`Case` says what a user should get: ``same`` (the clean mesh's surface, so its
quality: within 0.2 dB under the judge, checked by the benchmark), ``changed`` (another
surface that must construct, crack-free) or ``refuse`` (one line naming ``cause``)."""
from __future__ import annotations

import json
import struct
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from core.io.gltf import Builder, pack_glb  # noqa: E402
from core.io.ply import write_ply  # noqa: E402
from core.mesh.trimesh import TriMesh  # noqa: E402
from core.mesh.primitives import finned_sphere, noisy_sphere  # noqa: E402

OFFSETS = {"offset_2e5": (2e5, -3e5, 1e4), "offset_1e6": (1e6, -1e6, 1e6)}


@dataclass
class Case:
    name: str
    path: Path
    expect: str                       # "same", "changed" or "refuse"
    reference: Path | None = None     # what the result is judged against (its own frame)
    cause: str = ""                   # a refusal's line must contain this (case-insensitive)


def soup(mesh: TriMesh) -> TriMesh:
    """Every triangle with three vertices of its own."""
    return TriMesh(mesh.vertices[mesh.faces.reshape(-1)], np.arange(3 * mesh.n_faces).reshape(-1, 3))


def with_degenerate(mesh: TriMesh, share: float = 0.02, seed: int = 0) -> TriMesh:
    """``mesh`` plus zero-area faces: some repeat a vertex, some are collinear (a vertex on
    the middle of an edge)."""
    rng = np.random.default_rng(seed)
    n = max(2, int(share * mesh.n_faces))
    pick = mesh.faces[rng.choice(mesh.n_faces, n, replace=False)]
    half = n // 2
    repeated = np.column_stack([pick[:half, 0], pick[:half, 0], pick[:half, 1]])
    mid = mesh.vertices[pick[half:, 0]] / 2 + mesh.vertices[pick[half:, 1]] / 2
    m_idx = mesh.n_vertices + np.arange(len(mid))
    collinear = np.column_stack([pick[half:, 0], m_idx, pick[half:, 1]])
    faces = np.vstack([mesh.faces, repeated, collinear])
    order = rng.permutation(len(faces))
    return TriMesh(np.vstack([mesh.vertices, mid]), faces[order])


def with_t_junctions(mesh: TriMesh, n: int = 100, seed: int = 0) -> TriMesh:
    """``n`` faces split in two at the middle of one edge, their neighbours across it not:
    the new vertex lies on the neighbour's edge without being one of its vertices."""
    rng = np.random.default_rng(seed)
    picked = rng.choice(mesh.n_faces, n, replace=False)
    f = mesh.faces[picked]
    mid = mesh.vertices[f[:, 0]] / 2 + mesh.vertices[f[:, 1]] / 2
    m = mesh.n_vertices + np.arange(n)
    halves = np.vstack([np.column_stack([f[:, 0], m, f[:, 2]]), np.column_stack([m, f[:, 1], f[:, 2]])])
    return TriMesh(np.vstack([mesh.vertices, mid]), np.vstack([np.delete(mesh.faces, picked, 0), halves]))


def with_holes(mesh: TriMesh, n: int = 60, seed: int = 0) -> TriMesh:
    rng = np.random.default_rng(seed)
    return TriMesh(mesh.vertices, np.delete(mesh.faces, rng.choice(mesh.n_faces, n, replace=False), 0))


def many_parts(parts: int = 300, faces_each: int = 320, seed: int = 0) -> TriMesh:
    """``parts`` small noisy spheres on a grid."""
    k = int(np.ceil(parts ** (1 / 3)))
    vs, fs, off = [], [], 0
    for i in range(parts):
        v, f = noisy_sphere(faces_each, seed=seed + i)
        vs.append(0.4 * v + 1.2 * np.array([i % k, (i // k) % k, i // (k * k)], float))
        fs.append(f + off)
        off += len(v)
    return TriMesh(np.vstack(vs), np.vstack(fs))


def write_stl(path: Path, vertices: np.ndarray, faces: np.ndarray, ascii: bool = False) -> None:
    tri = vertices[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    if ascii:
        lines = ["solid corpus"]
        for nrm, t in zip(normal, tri):
            lines += [f"facet normal {nrm[0]:.9e} {nrm[1]:.9e} {nrm[2]:.9e}", " outer loop"]
            lines += [f"  vertex {p[0]:.9e} {p[1]:.9e} {p[2]:.9e}" for p in t]
            lines += [" endloop", "endfacet"]
        path.write_text("\n".join(lines + ["endsolid corpus", ""]))
        return
    rec = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = normal, tri
    path.write_bytes(b"solid binary STL written by the test corpus".ljust(80, b" ")
                     + struct.pack("<I", len(faces)) + rec.tobytes())


def write_gltf(path: Path, vertices: np.ndarray, faces: np.ndarray, edit=None) -> Path:
    """A plain glTF (``.glb``, or ``.gltf`` + ``.bin``) holding one triangle mesh as given;
    ``edit(doc)`` changes its JSON first."""
    b = Builder()
    pos = b.accessor(np.asarray(vertices, np.float32), "<f4", "POSITION", 34962)
    idx = b.accessor(np.asarray(faces, np.uint32).reshape(-1), "<u4", "indices", 34963)
    glb = path.suffix == ".glb"
    doc, blob = b.finish(None if glb else path.with_suffix(".bin").name)
    doc.update(meshes=[{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}],
               nodes=[{"mesh": 0}], scenes=[{"nodes": [0]}], scene=0)
    if edit is not None:
        edit(doc)
    if glb:
        path.write_bytes(pack_glb(doc, blob))
    else:
        path.with_suffix(".bin").write_bytes(blob)
        path.write_text(json.dumps(doc))
    return path


def write_usd(path: Path, ply: Path) -> None:
    """``ply`` exported as USD by Blender itself (a process of its own: it resets the scene)."""
    code = (f"import sys; sys.path.insert(0, {str(ROOT)!r}); import bpy; "
            "from core.io.mesh_files import read_mesh; "
            f"m = read_mesh({str(ply)!r}); bpy.ops.wm.read_factory_settings(use_empty=True); "
            "me = bpy.data.meshes.new('corpus'); me.from_pydata(m.vertices.tolist(), [], "
            "m.faces.tolist()); ob = bpy.data.objects.new('corpus', me); "
            "bpy.context.scene.collection.objects.link(ob); "
            f"bpy.ops.wm.usd_export(filepath={str(path)!r})")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)


def build(mesh: TriMesh, folder: Path, usd: bool = True, generated: bool = True) -> list[Case]:
    """The corpus of ``mesh`` in ``folder``; ``generated`` adds the fins sphere and the
    hundreds of parts, ``usd`` the USD copy (Blender's exporter, seconds)."""
    folder.mkdir(parents=True, exist_ok=True)
    clean = folder / "clean.ply"
    write_ply(clean, mesh.vertices, mesh.faces, double=True)
    cases = [Case("clean", clean, "same", clean)]

    def ply(name: str, m: TriMesh, expect: str, reference: Path | None = clean) -> None:
        path = folder / f"{name}.ply"
        write_ply(path, m.vertices, m.faces, double=True)
        cases.append(Case(name, path, expect, reference or path))

    s = soup(mesh)
    ply("soup", s, "same")
    rng = np.random.default_rng(1)
    ply("soup_jitter", TriMesh(s.vertices + rng.normal(size=s.vertices.shape) * 1e-8
                               * mesh.bbox_diagonal, s.faces), "same")
    for name, ascii in (("stl_binary", False), ("stl_ascii", True)):
        write_stl(folder / f"{name}.stl", mesh.vertices, mesh.faces, ascii)
        cases.append(Case(name, folder / f"{name}.stl", "same", clean))
    for name, t in OFFSETS.items():
        ply(name, TriMesh(mesh.vertices + np.array(t), mesh.faces), "same", None)
    ply("degenerate", with_degenerate(mesh), "same")
    ply("t_junctions", with_t_junctions(mesh), "same")
    ply("holes", with_holes(mesh), "changed", None)
    if generated:
        ply("fins_sphere", TriMesh(*finned_sphere(20000)), "changed", None)
        ply("parts_300", many_parts(), "changed", None)
    if usd:
        write_usd(folder / "usd.usdc", clean)
        cases.append(Case("usd", folder / "usd.usdc", "same", clean))
    cases += _refused(mesh, folder)
    return cases


def _refused(mesh: TriMesh, folder: Path) -> list[Case]:
    """Non-finite values in every input format, and broken files."""
    cases = []
    for name, (index, value), fmt in (("nan_ply", (5, np.nan), "ply"), ("inf_obj", (7, np.inf), "obj"),
                                      ("nan_stl", (0, np.nan), "stl")):
        v = mesh.vertices.copy()
        v[index] = value
        path = folder / f"{name}.{fmt}"
        if fmt == "ply":
            write_ply(path, v, mesh.faces)
        elif fmt == "obj":
            path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in v)
                            + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in mesh.faces))
        else:
            write_stl(path, v, mesh.faces)
        cases.append(Case(name, path, "refuse", cause=name[:3]))
    stl = (folder / "stl_binary.stl")
    if stl.exists():
        (folder / "cut.stl").write_bytes(stl.read_bytes()[:-30])
        cases.append(Case("truncated_stl", folder / "cut.stl", "refuse", cause=""))
    write_gltf(folder / "inf.glb", np.full_like(mesh.vertices, np.inf), mesh.faces)
    cases.append(Case("inf_glb", folder / "inf.glb", "refuse", cause=""))
    bad = mesh.faces.copy()
    bad[3, 1] = mesh.n_vertices + 10
    write_gltf(folder / "index.gltf", mesh.vertices, bad)
    cases.append(Case("index_gltf", folder / "index.gltf", "refuse", cause="range"))
    write_gltf(folder / "nobuffer.gltf", mesh.vertices, mesh.faces)
    (folder / "nobuffer.bin").unlink()
    cases.append(Case("missing_buffer_gltf", folder / "nobuffer.gltf", "refuse", cause=""))
    (folder / "notjson.gltf").write_text('{"asset": {"version": "2.0"}, "meshes": [ nope ]')
    cases.append(Case("not_json_gltf", folder / "notjson.gltf", "refuse", cause=""))
    return cases
