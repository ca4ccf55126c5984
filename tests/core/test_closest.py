"""BVH closest-point queries against brute force over all triangles."""
from __future__ import annotations

import numpy as np
import pytest

from core.spatial.closest import (ClosestPointError, ClosestPointIndex, closest_point_index,
                                  index_on)
from core.mesh.trimesh import TriMesh
from core.runtime.threads import default_threads, threads
from oracles import triangle_distances


def _check(idx, q, v, f, **kw):
    p, face, dist = idx.query(q, **kw)
    d = triangle_distances(q, v, f)
    best = d.min(1)
    assert np.allclose(dist, best, rtol=1e-12, atol=1e-12)
    # The reported face attains the minimum, and the reported point is on it, at that distance.
    assert np.allclose(d[np.arange(len(q)), face], best, rtol=1e-12, atol=1e-12)
    assert np.allclose(np.linalg.norm(p - q, axis=1), dist, rtol=1e-12, atol=1e-12)
    on = triangle_distances(p, v, f)[np.arange(len(q)), face]
    assert on.max() < 1e-12 * max(1.0, np.abs(v).max())
    return p, face, dist


def _blob(seed, n_faces=400, n_verts=120):
    """A random soup: uneven, crossing, with degenerate triangles (collinear, repeated corners)."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n_verts, 3))
    v[:6] *= 8                                             # a few huge triangles
    f = rng.integers(0, n_verts, size=(n_faces, 3))
    v = np.concatenate([v, [[0, 0, 0], [1, 1, 1], [2, 2, 2], [0.5, -1, 3]]])
    k = n_verts
    f = np.concatenate([f, [[k, k + 1, k + 2],             # collinear
                            [k + 3, k + 3, k],             # repeated corner: a segment
                            [k + 1, k + 1, k + 1],         # a point
                            [k, k + 1, k + 1 + 0]]])       # collinear, repeated corner
    return v, f


def _sphere(n_sub=3, r=1.5):
    from bench._common import icosphere  # noqa: PLC0415 - shared procedural mesh
    v, f = icosphere(n_sub, r)
    return v, f


@pytest.mark.parametrize("seed", [0, 1])
def test_random_soup_matches_brute_force(seed):
    v, f = _blob(seed)
    idx = ClosestPointIndex(v, f)
    rng = np.random.default_rng(10 + seed)
    near = v[rng.integers(0, len(v), 300)] + 0.05 * rng.normal(size=(300, 3))
    far = rng.normal(size=(100, 3)) * 40
    exact_vertices = v[rng.integers(0, len(v), 20)]       # distance exactly 0
    _, _, dist = _check(idx, np.concatenate([near, far, exact_vertices]), v, f)
    assert (dist[-20:] == 0).all()


def test_closest_point_regions_of_one_triangle():
    """The point-triangle routine's Voronoi regions (each vertex, each edge, the face), through
    the query as shipped."""
    idx = ClosestPointIndex(np.array([[0, 0, 0.], [1, 0, 0.], [0, 1, 0.]]), np.array([[0, 1, 2]]))
    cases = {(-1, -1, 0): (0, 0, 0), (2, -0.5, 1): (1, 0, 0), (-0.5, 3, 0): (0, 1, 0),
             (0.5, -1, 2): (0.5, 0, 0), (-1, 0.25, 0): (0, 0.25, 0), (1, 1, 0): (0.5, 0.5, 0),
             (0.2, 0.3, -4): (0.2, 0.3, 0)}
    for p, e in cases.items():
        cp, face, dist = idx.query(np.array([p], float))
        assert np.allclose(cp[0], e), (p, cp)
        assert face[0] == 0 and np.isclose(dist[0], np.linalg.norm(np.subtract(p, e)))


def test_sphere_near_far_inside():
    v, f = _sphere(6)
    idx = ClosestPointIndex(v, f)
    rng = np.random.default_rng(2)
    d = rng.normal(size=(600, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r = np.concatenate([1.5 + 1e-3 * rng.normal(size=300), rng.uniform(0, 1.4, 150),
                        rng.uniform(2, 30, 150)])          # near, inside, far
    q = d * r[:, None]
    q[0] = 0                                               # the centre: every face near-equidistant
    _check(idx, q, v, f)


def test_degenerate_only_mesh():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 0, 1]], float)
    f = np.array([[0, 1, 2], [3, 3, 3], [0, 0, 2]])
    idx = ClosestPointIndex(v, f)
    q = np.array([[1.0, 1.0, 0.0], [3.0, 0.0, 0.0], [0.0, 0.0, 2.0], [-1.0, 0.0, 0.0]])
    p, face, dist = _check(idx, q, v, f)
    assert np.allclose(dist, [1.0, 1.0, 1.0, 1.0])
    assert face[2] == 1 and np.allclose(p[2], [0, 0, 1])


def test_max_distance():
    v, f = _blob(3)
    idx = ClosestPointIndex(v, f)
    rng = np.random.default_rng(4)
    q = rng.normal(size=(300, 3)) * 6
    full_p, full_f, full_d = idx.query(q)
    limit = np.median(full_d)
    p, face, dist = idx.query(q, max_distance=limit)
    inside = full_d <= limit
    assert 0 < inside.sum() < len(q)
    assert np.array_equal(dist[inside], full_d[inside])
    assert np.array_equal(face[inside], full_f[inside])
    assert np.array_equal(p[inside], full_p[inside])
    assert np.isinf(dist[~inside]).all() and (face[~inside] == -1).all()
    assert np.isnan(p[~inside]).all()
    # Per-point bounds, and a bound of exactly the distance keeps the point.
    per = np.where(np.arange(len(q)) % 2 == 0, full_d, 0.5 * full_d)
    _, face2, dist2 = idx.query(q, max_distance=per)
    assert np.array_equal(dist2[::2], full_d[::2])
    far = (np.arange(len(q)) % 2 == 1) & (full_d > 0)
    assert (face2[far] == -1).all()
    # Zero bound: only points exactly on the surface.
    _, face0, dist0 = idx.query(np.concatenate([q[:3], v[f[:2, 0]]]), max_distance=0.0)
    assert (face0[:3] == -1).all() and (dist0[3:] == 0).all()


def test_empty_query_and_bad_input():
    v, f = _blob(0, 50, 30)
    idx = ClosestPointIndex(v, f)
    p, face, dist = idx.query(np.zeros((0, 3)))
    assert p.shape == (0, 3) and face.shape == (0,) and dist.shape == (0,)
    with pytest.raises(ClosestPointError):
        idx.query(np.zeros((4, 2)))
    with pytest.raises(ClosestPointError):
        idx.query(np.array([[0, 0, np.nan]]))
    with pytest.raises(ClosestPointError):
        idx.query(np.zeros((2, 3)), max_distance=-1.0)
    with pytest.raises(ClosestPointError):
        idx.query(np.zeros((2, 3)), max_distance=np.ones(3))
    with pytest.raises(ClosestPointError):
        ClosestPointIndex(v, np.zeros((0, 3), np.int64))
    with pytest.raises(ClosestPointError):
        ClosestPointIndex(v, np.array([[0, 1, len(v)]]))
    with pytest.raises(ClosestPointError):
        ClosestPointIndex(np.full((3, 3), np.inf), np.array([[0, 1, 2]]))
    with pytest.raises(ClosestPointError):
        ClosestPointIndex(v[:, :2], f)
    with pytest.raises(ClosestPointError):
        ClosestPointIndex(v, f.astype(float))
    assert issubclass(ClosestPointError, ValueError)


def test_thread_count_independence():
    v, f = _sphere(12)
    idx = ClosestPointIndex(v, f)
    rng = np.random.default_rng(5)
    # Vertices and edge midpoints lifted off the surface: ties between faces everywhere.
    q = np.concatenate([v * 1.01, 0.5 * (v[f[:, 0]] + v[f[:, 1]]) * 0.99,
                        rng.normal(size=(3000, 3))])
    ref = idx.query(q, threads=1)
    for t in range(2, max(default_threads(), 4) + 1):   # more than the cores: capped
        out = idx.query(q, threads=t)
        for a, b in zip(ref, out):
            assert np.array_equal(a, b)
    before = threads()
    idx.query(q[:10], threads=1)
    assert threads() == before


def test_cached_per_mesh():
    v, f = _sphere(2)
    m = TriMesh(v, f)
    assert closest_point_index(m) is closest_point_index(m)
    assert closest_point_index(TriMesh(v, f)) is not closest_point_index(m)


def test_a_refitted_tree_answers_as_a_new_one():
    """A tree built over some vertices, its boxes refitted to moved ones: the same answers as
    brute force; on the vertices it was built on, the same bits as the built index."""
    v, f = _blob(5)
    idx = ClosestPointIndex(v, f)
    rng = np.random.default_rng(6)
    q = np.concatenate([v[rng.integers(0, len(v), 300)] + 0.05 * rng.normal(size=(300, 3)),
                        rng.normal(size=(100, 3)) * 20])
    same = ClosestPointIndex.refitted(v, f, idx.tree)
    for a, b in zip(idx.query(q), same.query(q)):
        assert np.array_equal(a, b)
    moved = v + 0.3 * rng.normal(size=v.shape)
    _check(ClosestPointIndex.refitted(moved, f, idx.tree), q, moved, f)
    with pytest.raises(ClosestPointError):
        ClosestPointIndex.refitted(moved, f[:-1], idx.tree)
    with pytest.raises(ClosestPointError):
        ClosestPointIndex.refitted(np.full_like(v, np.nan), f, idx.tree)
    with pytest.raises(ClosestPointError):                 # checked as a new index's faces
        ClosestPointIndex.refitted(moved, f + len(v), idx.tree)


def test_one_tree_per_owner():
    """``index_on`` builds a tree for an owner once and refits it after that; a new owner
    gets a new tree."""
    class Owner:
        pass

    v, f = _sphere(8)
    owner = Owner()
    first = index_on(v, f, owner)
    moved = v * 1.1 + 0.01
    again = index_on(moved, f, owner)
    assert again.tree[0] is first.tree[0]                  # the same tree, refitted
    rng = np.random.default_rng(7)
    _check(again, rng.normal(size=(200, 3)) * 2, moved, f)
    assert index_on(moved, f, Owner()).tree[0] is not first.tree[0]
