"""Projection baking against known surfaces."""
from __future__ import annotations

import numpy as np
import pytest

from core.spatial.bake import (SOURCE_NEAREST, SOURCE_NEGATIVE, SOURCE_POSITIVE, BakeError,
                               bake_displacements, nearest_points)
from core.mesh.trimesh import TriMesh
from oracles import triangle_distances

R = 2.5


def _icosphere(n_sub: int, radius: float = 1.0):
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(n_sub):
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        ue, inv = np.unique(e, axis=0, return_inverse=True)
        mid = len(v) + inv.reshape(3, -1).T
        m = v[ue].mean(1)
        v = np.concatenate([v, m / np.linalg.norm(m, axis=1, keepdims=True)])
        a, b, c = f.T
        ab, bc, ca = mid.T
        f = np.concatenate([np.stack(x, 1) for x in ([a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca])])
    return TriMesh(v * radius, f)


@pytest.fixture(scope="module")
def sphere():
    return _icosphere(6, R)  # 81920 faces: chord error ~3e-4·R; tests compare with the mesh


@pytest.fixture(scope="module")
def base_samples():
    """Points on the (flat) icosahedron faces with interpolated vertex normals and radial dirs."""
    base = _icosphere(0, 0.8 * R)
    rng = np.random.default_rng(0)
    bc = rng.dirichlet([1, 1, 1], size=3000)
    fid = rng.integers(0, base.n_faces, 3000)
    tri = base.vertices[base.faces[fid]]
    o = np.einsum("nk,nkj->nj", bc, tri)
    nv = base.vertex_normals[base.faces[fid]]
    dn = np.einsum("nk,nkj->nj", bc, nv)
    dn /= np.linalg.norm(dn, axis=1, keepdims=True)
    return o, dn


def _on_mesh_error(points, mesh):
    return nearest_points(points, mesh)[2]


def test_radial_directions_reach_the_sphere(sphere, base_samples):
    o, _ = base_samples
    d = 0.37 * o  # radial, deliberately not unit
    res = bake_displacements(o, d, sphere)
    assert (res.source == SOURCE_POSITIVE).all()
    hit = o + d * res.displacement[:, None]
    assert np.abs(np.linalg.norm(hit, axis=1) - R).max() < 1e-3 * R   # the sphere (mesh chord)
    assert _on_mesh_error(hit, sphere).max() < 1e-4 * R               # exactly on the mesh
    assert np.allclose(res.distance, np.linalg.norm(hit - o, axis=1))


def test_interpolated_normals_and_negative_hits(sphere, base_samples):
    o, dn = base_samples
    # Push the origins outside the sphere: now the surface is behind them (−direction).
    o_out = o * (1.3 * R / np.linalg.norm(o, axis=1, keepdims=True))
    for origins, expect in ((o, SOURCE_POSITIVE), (o_out, SOURCE_NEGATIVE)):
        res = bake_displacements(origins, dn, sphere)
        assert (res.source == expect).all()
        hit = origins + dn * res.displacement[:, None]
        assert _on_mesh_error(hit, sphere).max() < 1e-4 * R
        assert np.abs(np.linalg.norm(hit, axis=1) - R).max() < 1e-3 * R
        assert ((res.displacement > 0) == (expect == SOURCE_POSITIVE)).all()


def test_nearer_of_both_hits_wins():
    # Two parallel planes z = 1 and z = −0.5: from the origin the −z plane is nearer.
    v = np.array([[-5, -5, 1], [5, -5, 1], [5, 5, 1], [-5, 5, 1],
                  [-5, -5, -0.5], [5, -5, -0.5], [5, 5, -0.5], [-5, 5, -0.5]], float)
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    m = TriMesh(v, f)
    o = np.array([[0.1, 0.2, 0.0], [0.3, -0.1, 0.4]])
    d = np.array([[0, 0, 2.0], [0, 0, 2.0]])
    res = bake_displacements(o, d, m)
    assert res.source.tolist() == [SOURCE_NEGATIVE, SOURCE_POSITIVE]
    assert res.displacement == pytest.approx([-0.25, 0.3], abs=1e-12)
    assert res.distance == pytest.approx([0.5, 0.6], abs=1e-12)


def test_max_distance_uses_nearest_point_fallback(sphere, base_samples):
    o, _ = base_samples
    o, d = o[:500], o[:500] * 2.0
    gap = R - np.linalg.norm(o, axis=1)                      # ray distance to the sphere
    limit = np.where(np.arange(len(o)) % 2 == 0, gap * 0.5, gap * 1.5)
    # A skewed direction: the projection of the nearest point differs from the ray hit.
    d_skew = d + np.cross(d, [0.3, 0.1, 0.2])
    res = bake_displacements(o, d_skew, sphere, max_distance=limit)
    far = limit < gap
    assert (res.source[far] == SOURCE_NEAREST).all()
    p, _, pd = nearest_points(o[far], sphere)
    dd = d_skew[far]
    expect = np.einsum("ij,ij->i", dd, p - o[far]) / np.einsum("ij,ij->i", dd, dd)
    assert np.allclose(res.displacement[far], expect, atol=1e-12)
    assert np.allclose(res.distance[far], pd)
    assert ((res.source[~far] == SOURCE_POSITIVE) | (res.source[~far] == SOURCE_NEAREST)).all()
    # Scalar limit too: nothing within 1e-6 → all fallback.
    assert (bake_displacements(o, d, sphere, max_distance=1e-6).source == SOURCE_NEAREST).all()


def test_zero_direction_and_miss_fall_back_without_nan(sphere):
    o = np.array([[0.0, 0.0, 0.0], [3 * R, 0, 0]])
    d = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]])      # zero; a ray that misses both ways
    res = bake_displacements(o, d, sphere)
    assert res.source.tolist() == [SOURCE_NEAREST, SOURCE_NEAREST]
    assert np.isfinite(res.displacement).all()
    assert res.displacement[0] == 0.0
    assert res.distance[1] == pytest.approx(2 * R, rel=1e-3)


def test_nearest_points_exact_against_brute_force():
    rng = np.random.default_rng(3)
    # Very uneven, crossing triangles (large boxes overlap everything in the BVH).
    v = rng.normal(size=(60, 3))
    v[:5] *= 20
    f = rng.integers(0, 60, size=(150, 3))
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    m = TriMesh(v, f)
    q = rng.normal(size=(400, 3)) * 3
    p, face, dist = nearest_points(q, m)
    brute = triangle_distances(q, v, f).min(1)
    assert np.allclose(dist, brute, atol=1e-12)
    assert np.allclose(np.linalg.norm(p - q, axis=1), dist)


def test_bad_input(sphere):
    o = np.zeros((3, 3))
    with pytest.raises(BakeError):
        bake_displacements(o, np.ones((2, 3)), sphere)
    with pytest.raises(BakeError):
        bake_displacements(np.full((3, 3), np.nan), np.ones((3, 3)), sphere)
    with pytest.raises(BakeError):
        bake_displacements(o, np.ones((3, 2)), sphere)
    with pytest.raises(BakeError):
        bake_displacements(o, np.ones((3, 3)), sphere, max_distance=-1.0)
    with pytest.raises(BakeError):
        bake_displacements(o, np.ones((3, 3)), sphere, max_distance=np.ones(4))
