"""Micro-mesh topology: counts, orders, balancing, flags, canonical space, watertightness."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from shapes import icosahedron, icosphere, torus
from core.mesh.trimesh import TriMesh
from core.micro.levels import balance_levels, count_micro_vertices, edge_flags
from core.micro.topology import (MAX_LEVEL, LevelError, barycentric_weights, bird_index,
                                 bird_order, build_topology, level_grid, level_triangles,
                                 n_micro_triangles, n_micro_vertices, snap_targets, umajor_index)


# ------------------------------------------------------------------ test meshes
MESHES = {"ico": icosahedron(), "sphere": icosphere(1), "torus": torus()}


def directed_edge_check(tris: np.ndarray) -> tuple[int, int]:
    """(boundary edges, edges used more than twice or not in opposite pairs)."""
    he = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    key = np.sort(he, 1)
    uk, cnt = np.unique(key, axis=0, return_counts=True)
    uh, hcnt = np.unique(he, axis=0, return_counts=True)
    return int((cnt == 1).sum()), int((cnt > 2).sum() + (hcnt > 1).sum())


# ------------------------------------------------------------------ per level
@pytest.mark.parametrize("level", range(6))
def test_counts_grid_and_triangles(level):
    s = 1 << level
    g = level_grid(level)
    assert n_micro_vertices(level) == (s + 1) * (s + 2) // 2 == len(g)
    assert n_micro_triangles(level) == 4 ** level == len(level_triangles(level))
    assert (umajor_index(g[:, 0], g[:, 1], level) == np.arange(len(g))).all()
    assert (g.sum(1) <= s).all() and (g >= 0).all()
    assert len({tuple(x) for x in g}) == len(g)
    bw = barycentric_weights(level)
    assert np.allclose(bw.sum(1), 1)
    t = level_triangles(level)
    p = g[t].astype(float)
    area2 = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - \
        (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0])
    assert np.allclose(area2, 1.0)  # all wound like (W, U, V), unit area in grid units
    assert directed_edge_check(t)[1] == 0


def test_umajor_formula_by_hand():
    # level 1: (0,0)=0 (0,1)=1 (0,2)=2 (1,0)=3 (1,1)=4 (2,0)=5
    assert list(umajor_index([0, 0, 0, 1, 1, 2], [0, 1, 2, 0, 1, 0], 1)) == [0, 1, 2, 3, 4, 5]
    assert umajor_index(4, 0, 2) == 4 * 6 - 10 + 0 == 14


def test_bird_level2_check_vector():
    rows = [[0, 8, 5, 11, 1], [6, 7, 9, 10], [3, 14, 4], [12, 13], [2]]
    inv = bird_index(2)
    got = [[int(inv[umajor_index(u, v, 2)]) for u in range(5 - v)] for v in range(5)]
    assert got == rows
    order = bird_order(2)
    assert (inv[order] == np.arange(15)).all()


@pytest.mark.parametrize("level", range(6))
def test_bird_is_permutation_with_corners_first(level):
    o = bird_order(level)
    assert sorted(o) == list(range(n_micro_vertices(level)))
    s = 1 << level
    assert list(o[:3]) == [0, umajor_index(s, 0, level), umajor_index(0, s, level)][:len(o[:3])]
    if level >= 1:  # the level-(ℓ-1) vertices come first, in their own bird order
        g, gp = level_grid(level), level_grid(level - 1)
        prev = gp[bird_order(level - 1)] * 2
        assert (g[o[:len(prev)]] == prev).all()


def test_bad_levels_rejected():
    with pytest.raises(LevelError):
        level_grid(MAX_LEVEL + 1)
    with pytest.raises(LevelError):
        balance_levels(icosahedron(), np.zeros(3))
    with pytest.raises(LevelError):
        build_topology(icosahedron(), np.r_[3, np.zeros(19, int)])


# ------------------------------------------------------------------ balancing, flags
def _edge_level_spread(mesh, lv):
    ptr, idx = mesh.edge_faces_csr
    v = lv[idx]
    return np.maximum.reduceat(v, ptr[:-1]) - np.minimum.reduceat(v, ptr[:-1])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), name=st.sampled_from(sorted(MESHES)))
def test_balance_property(seed, name):
    mesh = MESHES[name]
    raw = np.random.default_rng(seed).integers(-1, MAX_LEVEL + 3, mesh.n_faces)
    lv = balance_levels(mesh, raw)
    assert (_edge_level_spread(mesh, lv) <= 1).all()
    assert (lv >= np.clip(raw, 0, MAX_LEVEL)).all() and lv.min() >= 0 and lv.max() <= MAX_LEVEL
    assert (balance_levels(mesh, lv) == lv).all()  # idempotent
    fl = edge_flags(mesh, lv)
    adj = mesh.face_adjacency
    for i in range(3):
        has = adj[:, i] >= 0
        lower = np.zeros(mesh.n_faces, bool)
        lower[has] = lv[adj[has, i]] == lv[has] - 1
        assert (((fl >> i) & 1).astype(bool) == lower).all()


def test_balance_nonmanifold_edge():
    # three triangles on one edge (0, 1)
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], float)
    m = TriMesh(v, [[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    lv = balance_levels(m, [0, 0, 3])
    assert list(lv) == [2, 2, 3]
    assert list(edge_flags(m, lv)) == [0, 0, 1]
    t = build_topology(m, lv)
    assert t.edge_levels[0] == 2 and t.n_vertices == count_micro_vertices(m, lv)


# ------------------------------------------------------------------ canonical space
@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), name=st.sampled_from(sorted(MESHES)))
def test_watertight_random_levels(seed, name):
    mesh = MESHES[name]
    rng = np.random.default_rng(seed)
    lv = balance_levels(mesh, rng.integers(0, 4, mesh.n_faces))
    t = build_topology(mesh, lv)
    assert t.n_vertices == count_micro_vertices(mesh, lv)
    # canonical index space: closed and consistently oriented
    assert directed_edge_check(t.triangles) == (0, 0)
    # every canonical vertex is used, interp rows sum to 1
    assert np.array_equal(np.unique(t.triangles), np.arange(t.n_vertices))
    assert np.allclose(np.asarray(t.interp.sum(1)).ravel(), 1.0)
    # welded by position: still closed
    pos = t.interp @ mesh.vertices
    _, weld = np.unique(np.round(pos, 9), axis=0, return_inverse=True)
    wt = weld.reshape(-1)[t.triangles]
    assert not ((wt[:, 0] == wt[:, 1]) | (wt[:, 1] == wt[:, 2]) | (wt[:, 2] == wt[:, 0])).any()
    assert directed_edge_check(wt)[0] == 0
    # degenerate micro-triangles only where snapping says so
    fl = t.flags
    expected = 0
    for f in range(mesh.n_faces):
        lvl = int(lv[f])
        tgt = snap_targets(lvl, int(fl[f]))
        lt = tgt[level_triangles(lvl)]
        deg = (lt[:, 0] == lt[:, 1]) | (lt[:, 1] == lt[:, 2]) | (lt[:, 2] == lt[:, 0])
        expected += int(deg.sum())
        # the vectorised build agrees with the per-face snapping rule
        local = t.face_vertices(f)
        assert (local[tgt] == local).all()
        assert len(np.unique(local)) == len(np.unique(tgt))
    assert len(t.triangles) == (4 ** lv).sum() - expected
    p = pos[t.triangles]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    assert area.min() > 1e-8
    # orientation matches the base face
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert ((n * mesh.face_normals[t.triangle_face]).sum(1) > 0).all()


def test_shared_edge_same_vertices_both_sides():
    mesh = icosahedron()
    lv = balance_levels(mesh, np.r_[3, np.full(19, 2)])
    t = build_topology(mesh, lv)
    g = t.interp @ mesh.vertices
    for f in range(mesh.n_faces):
        loc = t.face_vertices(f)
        bw = barycentric_weights(int(lv[f]))
        moved = snap_targets(int(lv[f]), int(t.flags[f])) != np.arange(len(loc))
        want = bw @ mesh.vertices[mesh.faces[f]]
        assert np.allclose(g[loc][~moved], want[~moved])  # unsnapped at their grid point
        assert (t.vertex_face[loc] >= 0).all()
    vb = np.einsum("nk,nkc->nc", t.vertex_bary, mesh.vertices[mesh.faces[t.vertex_face]])
    assert np.allclose(vb, g)


def test_snap_towards_nearer_end():
    tg = snap_targets(3, 1)  # edge 0 (v = 0) decimated, level 3
    u = level_grid(3)[tg[umajor_index(np.arange(9), 0, 3)], 0]
    assert list(u) == [0, 0, 2, 2, 4, 6, 6, 8, 8]
    assert (tg[umajor_index(1, 1, 3)] == umajor_index(1, 1, 3))  # interior untouched


def test_counts_uniform_and_speed_scale():
    mesh = icosphere(2)  # 320 faces
    t = build_topology(mesh, np.full(mesh.n_faces, 4))
    assert t.n_triangles == 320 * 256
    # Euler: closed genus-0 → V − E + F = 2 with E = 3F/2
    assert t.n_vertices - 3 * t.n_triangles // 2 + t.n_triangles == 2
    assert t.face_triangle_ptr[-1] == t.n_triangles
    assert (np.diff(t.triangle_face) >= 0).all()
