"""TriMesh topology and unit-sphere normalisation."""
from __future__ import annotations

import numpy as np
import pytest

from shapes import torus
from core.mesh.trimesh import MeshError, TriMesh
from core.mesh.normalization import unit_sphere_normalization


def tetrahedron() -> TriMesh:
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return TriMesh(v, f)


def test_closed_tetrahedron_topology():
    m = tetrahedron()
    assert m.edges.shape == (6, 2)
    assert (m.edges[:, 0] < m.edges[:, 1]).all()
    assert m.is_closed_manifold and m.genus == 0 and m.n_components == 1
    assert len(m.boundary_edges) == 0 and len(m.nonmanifold_edges) == 0
    # Every face touches the other three across its edges and shares vertices with all.
    for f in range(4):
        assert sorted(m.face_adjacency[f]) == sorted(set(range(4)) - {f})
        ptr, idx = m.face_neighbors_csr
        assert sorted(idx[ptr[f]:ptr[f + 1]]) == sorted(set(range(4)) - {f})
    # face_edges agree with the edge table.
    for f in range(4):
        for i in range(3):
            a, b = m.faces[f, i], m.faces[f, (i + 1) % 3]
            assert tuple(m.edges[m.face_edges[f, i]]) == (min(a, b), max(a, b))
    ptr, idx = m.vertex_neighbors_csr
    assert list(np.diff(ptr)) == [3, 3, 3, 3]


def test_torus_genus_one_and_open_strip():
    t = torus()
    assert t.is_closed_manifold and t.genus == 1
    strip = TriMesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]]),
                    np.array([[0, 1, 2], [0, 2, 3]]))
    assert len(strip.boundary_edges) == 4
    assert strip.genus is None
    assert (strip.face_adjacency == -1).sum() == 4


def test_components_and_nonmanifold():
    a = tetrahedron()
    b_faces = a.faces + 4
    two = TriMesh(np.vstack([a.vertices, a.vertices + 5]), np.vstack([a.faces, b_faces]))
    assert two.n_components == 2 and two.genus == 0
    fin = TriMesh(np.vstack([a.vertices, [[1, 1, 1.0]]]), np.vstack([a.faces, [[1, 2, 4]]]))
    assert len(fin.nonmanifold_edges) == 1
    # Across a non-manifold edge no face is reported as the unique neighbour.
    e = fin.nonmanifold_edges[0]
    f, i = np.argwhere(fin.face_edges == e)[0]
    assert fin.face_adjacency[f, i] == -1


def test_geometry_quantities():
    m = tetrahedron()
    assert np.isclose(m.face_areas.sum(), 1.5 + np.sqrt(3) / 2)
    assert np.isclose(m.vertex_areas.sum(), m.face_areas.sum())
    assert np.allclose(np.linalg.norm(m.vertex_normals, axis=1), 1)
    # Outward normals of a closed mesh: the normal at vertex 3 points up and out.
    assert m.vertex_normals[3] @ np.array([0, 0, 1.0]) > 0


def test_with_vertices_shares_topology():
    m = tetrahedron()
    _ = m.face_adjacency
    moved = m.with_vertices(m.vertices * 2)
    assert moved.__dict__["face_adjacency"] is m.__dict__["face_adjacency"]
    assert np.isclose(moved.face_areas.sum(), 4 * m.face_areas.sum())
    with pytest.raises(MeshError):
        m.with_vertices(m.vertices[:3])


def test_normalization_round_trip():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(100, 3)) * 7 + 3
    n = unit_sphere_normalization(v)
    u = n.apply(v)
    assert np.isclose(np.linalg.norm(u, axis=1).max(), 1.0)
    assert np.allclose(n.invert(u), v)
    assert np.isclose(n.invert_volume(n.scale ** 3), 1.0)


@pytest.mark.parametrize("v,f,msg", [
    (np.zeros((3, 2)), [[0, 1, 2]], "vertices"),
    (np.zeros((3, 3)), [[0, 1, 3]], "range"),
    (np.full((3, 3), np.nan), [[0, 1, 2]], "NaN"),
    (np.zeros((3, 3)), np.zeros((0, 3)), "no faces"),
])
def test_bad_input_is_a_clear_error(v, f, msg):
    with pytest.raises(MeshError, match=msg):
        TriMesh(np.asarray(v), np.asarray(f))
