"""MicroMesh: validation, positions, tessellation, resampling on level changes, export order."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from shapes import icosahedron, torus
from core.micro.micromesh import MicroMesh, MicroMeshError, Tessellation
from core.micro.levels import balance_levels
from core.micro.topology import barycentric_weights, bird_order, snap_targets, umajor_index


def closed(tris: np.ndarray) -> bool:
    he = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    _, cnt = np.unique(np.sort(he, 1), axis=0, return_counts=True)
    _, hcnt = np.unique(he, axis=0, return_counts=True)
    return bool((cnt == 2).all() and (hcnt == 1).all())


def distance_to_triangles(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Brute-force distance from each point to the nearest of triangles (T, 3, 3)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    out = np.empty(len(points))
    for s in range(0, len(points), 256):
        p = points[s:s + 256, None, :]
        h = ((p - a) * n).sum(-1)
        q = p - h[..., None] * n
        inside = np.ones(h.shape, bool)
        for x, y in ((a, b), (b, c), (c, a)):
            inside &= (np.cross(y - x, q - x) * n).sum(-1) >= -1e-10
        d = np.where(inside, np.abs(h), np.inf)
        for x, y in ((a, b), (b, c), (c, a)):  # nearest point on an edge
            e = y - x
            t = np.clip(((p - x) * e).sum(-1) / (e * e).sum(-1), 0, 1)
            d = np.minimum(d, np.linalg.norm(p - (x + t[..., None] * e), axis=-1))
        out[s:s + 256] = d.min(1)
    return out


def random_mm(mesh, seed, max_level=3, directions=None, amp=0.05):
    rng = np.random.default_rng(seed)
    mm = MicroMesh.flat(mesh, rng.integers(0, max_level + 1, mesh.n_faces), directions)
    return mm.with_displacements(amp * rng.standard_normal(mm.n_vertices))


# ------------------------------------------------------------------ basics
def test_flat_defaults_and_positions():
    mesh = icosahedron()
    mm = MicroMesh.flat(mesh, np.r_[3, np.zeros(19, int)])
    assert (mm.levels == balance_levels(mesh, mm.levels)).all() and mm.levels.max() == 3
    assert np.allclose(mm.directions, mesh.direction_normals)
    assert (mm.displacements == 0).all()
    assert np.allclose(mm.micro_vertex_positions(), mm.topology.interp @ mesh.vertices)


def test_positions_match_per_face_formula():
    mesh = icosahedron()
    mm = random_mm(mesh, 3)
    pos = mm.micro_vertex_positions()
    t = mm.topology
    for f in range(mesh.n_faces):
        lv = int(mm.levels[f])
        moved = snap_targets(lv, int(t.flags[f])) != np.arange(len(t.face_vertices(f)))
        bw = barycentric_weights(lv)
        P = bw @ mesh.vertices[mesh.faces[f]]
        D = bw @ mm.directions[mesh.faces[f]]  # interpolated, not normalised
        d = mm.displacements[t.face_vertices(f)]
        assert np.allclose((P + D * d[:, None])[~moved], pos[t.face_vertices(f)][~moved])


def test_validation_errors():
    mesh = icosahedron()
    mm = MicroMesh.flat(mesh, 1)
    with pytest.raises(MicroMeshError, match="directions"):
        MicroMesh(mesh, np.zeros((3, 3)), mm.levels, mm.displacements)
    with pytest.raises(MicroMeshError, match="displacements"):
        MicroMesh(mesh, mm.directions, mm.levels, np.zeros(5))
    with pytest.raises(MicroMeshError, match="differ by at most one"):
        MicroMesh(mesh, mm.directions, np.r_[3, np.zeros(19, int)], np.zeros(5))
    with pytest.raises(MicroMeshError):
        MicroMesh(mesh, mm.directions, mm.levels, np.full(mm.n_vertices, np.nan))
    with pytest.raises(ValueError):
        mm.face_values("zigzag")
    assert isinstance(mm, MicroMesh) and issubclass(MicroMeshError, ValueError)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), use_torus=st.booleans())
def test_tessellation_watertight(seed, use_torus):
    mesh = torus(10, 6) if use_torus else icosahedron()
    mm = random_mm(mesh, seed)
    tess = mm.tessellate()
    assert isinstance(tess, Tessellation)
    assert closed(tess.triangles)
    _, weld = np.unique(tess.vertices.round(10), axis=0, return_inverse=True)
    w = weld.reshape(-1)[tess.triangles]
    assert closed(w)
    assert len(tess.triangle_face) == len(tess.triangles)


def test_face_values_shared_edges_and_bird():
    mesh = icosahedron()
    mm = random_mm(mesh, 7, max_level=2)
    ptr, um = mm.face_values("umajor")
    ptr2, bird = mm.face_values("bird")
    assert (ptr == ptr2).all()
    for f in range(mesh.n_faces):
        lv = int(mm.levels[f])
        a, b = um[ptr[f]:ptr[f + 1]], bird[ptr[f]:ptr[f + 1]]
        assert (b == a[bird_order(lv)]).all()
    # a shared edge seen from both faces: same bits
    f0 = 0
    f1 = mesh.face_adjacency[0, 0]
    va, vb = mesh.faces[f0, 0], mesh.faces[f0, 1]
    pos = mm.topology.interp @ mesh.vertices

    def edge_values(f):
        loc = mm.topology.face_vertices(f)
        on = np.isclose(np.cross(pos[loc] - mesh.vertices[va],
                                 mesh.vertices[vb] - mesh.vertices[va]), 0, atol=1e-12).all(1)
        key = np.linalg.norm(pos[loc][on] - mesh.vertices[va], axis=1)
        vals = um[ptr[f]:ptr[f + 1]][on]
        return {round(k, 9): v for k, v in zip(key, vals)}

    e0, e1 = edge_values(f0), edge_values(f1)
    common = set(e0) & set(e1)
    assert len(common) >= 3
    assert all(e0[k] == e1[k] for k in common)


def test_with_base_positions_shares_topology():
    mesh = icosahedron()
    mm = random_mm(mesh, 1)
    topo = mm.topology
    m2 = mm.with_base_positions(mesh.vertices * 2)
    assert m2.topology is topo
    assert np.allclose(m2.micro_vertex_positions() - mm.micro_vertex_positions(),
                       topo.interp @ mesh.vertices)


# ------------------------------------------------------------------ resampling
@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1))
def test_subdivided_parallel_directions_keeps_surface(seed):
    mesh = icosahedron()
    rng = np.random.default_rng(seed)
    c = rng.standard_normal(3)
    mm = random_mm(mesh, seed, max_level=2, directions=np.tile(c, (mesh.n_vertices, 1)))
    mask = rng.random(mesh.n_faces) < 0.5
    new = mm.subdivided(mask)
    assert (new.levels >= np.minimum(mm.levels + mask, 5)).all()
    old_tri = mm.micro_vertex_positions()[mm.topology.triangles]
    dist = distance_to_triangles(new.micro_vertex_positions(), old_tri)
    assert dist.max() < 1e-12
    # vertices that exist at both levels keep their exact value
    back = new.with_levels(mm.levels)
    assert np.array_equal(back.displacements, mm.displacements)


def test_linear_interpolation_reduces_for_parallel_directions():
    mesh = icosahedron()
    mm = random_mm(mesh, 5, max_level=0, directions=np.tile([0, 0, 1.0], (12, 1)))
    new = mm.subdivided()
    t = new.topology
    # level 0 → 1: edge midpoints get the mean of the two end values
    e = mesh.edges
    mids = t.edge_vertex_offset[:-1]
    assert np.allclose(new.displacements[mids],
                       0.5 * (mm.displacements[e[:, 0]] + mm.displacements[e[:, 1]]), atol=1e-14)


def test_subdivided_varying_directions_small_error():
    mesh = icosahedron()
    mm = random_mm(mesh, 11, max_level=2, amp=0.02)  # vertex-normal directions
    new = mm.subdivided()
    t = new.topology
    sel = np.arange(t.n_base_vertices, t.n_vertices)
    X = mm.surface_at(t.vertex_face[sel], t.vertex_bary[sel])
    err = np.linalg.norm(new.micro_vertex_positions()[sel] - X, axis=1)
    # residual ⟂ D is Σ b_k (D_k − D) d_k: bounded by max|d| · max|ΔD| over a micro-triangle
    idx, _ = mm.locate(t.vertex_face[sel], t.vertex_bary[sel])
    Dn = new.micro_vertex_directions()[sel]
    dD = np.linalg.norm(mm.micro_vertex_directions()[idx] - Dn[:, None], axis=-1).max(1)
    assert (err <= np.abs(mm.displacements).max() * dD + 1e-15).all()
    assert 0 < err.max() < 0.5 * np.abs(mm.displacements).max()
    old_tri = mm.micro_vertex_positions()[mm.topology.triangles]
    assert distance_to_triangles(new.micro_vertex_positions()[sel], old_tri).max() <= \
        err.max() + 1e-12


def test_sphere_example():
    mesh = icosahedron()
    mm = MicroMesh.flat(mesh, 2, directions=mesh.vertices)  # radial, unit at base vertices
    base = mm.micro_vertex_base_positions()
    dirs = mm.micro_vertex_directions()
    # radial directions: lerp(P)·(1 + d) lands on the unit sphere for d = 1/|lerp P| − 1
    sph = mm.with_displacements(1 / np.linalg.norm(base, axis=1) - 1)
    assert np.allclose(dirs, base)
    assert np.allclose(np.linalg.norm(sph.micro_vertex_positions(), axis=1), 1)
    fine = sph.subdivided()
    r = np.linalg.norm(fine.micro_vertex_positions(), axis=1)
    assert r.max() <= 1 + 1e-12 and r.min() > 0.95  # on the inscribed level-2 polyhedron
    t = fine.topology
    # the level-2 vertices are still on the sphere (kept exactly)
    coarse_pts = np.isin(np.round(fine.micro_vertex_base_positions(), 9).view("f8,f8,f8"),
                         np.round(base, 9).view("f8,f8,f8")).ravel()
    assert coarse_pts.sum() == sph.n_vertices
    assert np.allclose(r[coarse_pts], 1)
    assert len(t.triangles) == 20 * 64


def test_with_levels_down_and_errors():
    mesh = torus(10, 6)
    mm = random_mm(mesh, 2, max_level=3)
    down = mm.with_levels(np.maximum(mm.levels - 1, 0) * 0)
    assert down.n_vertices == mesh.n_vertices
    assert np.array_equal(down.displacements, mm.displacements[:mesh.n_vertices])
    with pytest.raises(MicroMeshError):
        mm.with_levels(np.r_[3, np.zeros(mesh.n_faces - 1, int)])
    assert mm.subdivided().levels.min() >= 1
    five = MicroMesh.flat(mesh, 5)
    assert (five.subdivided(np.ones(mesh.n_faces, bool)).levels == 5).all()


def test_umajor_used_in_face_values():
    mesh = icosahedron()
    mm = random_mm(mesh, 9, max_level=2)
    ptr, vals = mm.face_values()
    f = int(np.argmax(mm.levels))
    lv = int(mm.levels[f])
    i = umajor_index(1, 1, lv)
    assert vals[ptr[f] + i] == mm.displacements[mm.topology.face_vertices(f)[i]]
