"""The base builder's crease planes: they hold a short edge between large faces as firmly as
those faces hold their planes, keep their edge length² where that is more, and sit only on
edges sharper than the feature angle and than the surface around them."""
import numpy as np
import pytest

from core.base.quadrics import CREASE_AREA, crease_edges, quadric_error, vertex_quadrics
from core.mesh.trimesh import TriMesh


def crease(edge_length, depth, bend_deg=90.0):
    """Two triangles on the edge (0,0,0)-(edge_length,0,0), one in the plane z = 0 (apex at
    y = depth), the other bent up by ``bend_deg`` from that plane about the edge (0: flat).
    Boundary planes are switched off where this is used."""
    t = np.radians(bend_deg)
    v = np.array([[0.0, 0, 0], [edge_length, 0, 0], [edge_length / 2, depth, 0],
                  [edge_length / 2, -depth * np.cos(t), depth * np.sin(t)]])
    return TriMesh(v, np.array([[0, 1, 2], [1, 0, 3]]))


def cost_of_sliding_across(mesh, t):
    """Quadric error of vertex 0 moved by ``t`` within the first face's plane, across the
    crease (along +y), with the crease planes only (no boundary planes)."""
    Q, _ = vertex_quadrics(mesh, boundary_weight=0.0, crease_weight=1.0)
    Qf, _ = vertex_quadrics(mesh, boundary_weight=0.0, crease_weight=0.0)
    p = np.array([[0.0, t, 0.0]])
    return float(quadric_error(Q[:1], p)[0] - quadric_error(Qf[:1], p)[0])


@pytest.mark.parametrize("edge_length, depth", [(0.01, 1.0), (0.1, 1.0), (1.0, 0.05)])
def test_a_crease_plane_weighs_at_least_its_faces(edge_length, depth):
    mesh = crease(edge_length, depth)
    t = 1e-3
    held = cost_of_sliding_across(mesh, t)
    # Planes perpendicular to each face through the edge: at 90° the first one is at
    # distance t, the second one contains the move.
    weight = max(edge_length ** 2, CREASE_AREA * mesh.face_areas.sum())
    np.testing.assert_allclose(held, weight * t * t, rtol=1e-9)


def test_equilateral_creases_weigh_twice_their_edge_length_squared():
    mesh = crease(1.0, np.sqrt(3) / 2)
    np.testing.assert_allclose(cost_of_sliding_across(mesh, 1e-3), 2e-6, rtol=1e-9)


def test_flat_edges_get_no_crease_planes():
    mesh = crease(0.01, 1.0, bend_deg=10.0)           # below the feature angle
    assert cost_of_sliding_across(mesh, 1e-3) == pytest.approx(0.0, abs=1e-18)


def uv_sphere(segments, rings):
    """A closed UV sphere: ``segments`` facets around, ``rings`` bands from pole to pole
    (planar quads split in two, fans at the poles)."""
    lat = np.linspace(0.0, np.pi, rings + 1)[1:-1]
    lon = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    v = [[0.0, 0.0, 1.0]] + [[np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)]
                             for t in lat for p in lon] + [[0.0, 0.0, -1.0]]

    def ring(i, j):                                   # vertex j of latitude i
        return 1 + i * segments + j % segments

    f = [[0, ring(0, j), ring(0, j + 1)] for j in range(segments)]
    for i in range(rings - 2):
        for j in range(segments):
            a, b, c, d = ring(i, j), ring(i, j + 1), ring(i + 1, j), ring(i + 1, j + 1)
            f += [[a, c, b], [b, c, d]]
    last = len(v) - 1
    f += [[last, ring(rings - 2, j + 1), ring(rings - 2, j)] for j in range(segments)]
    return TriMesh(np.array(v), np.array(f))


def prism(segments, length=4.0):
    """An open straight tube of ``segments`` flat facets (one band of quads split in two)."""
    p = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    v = np.concatenate([np.stack([np.cos(p), np.sin(p), np.full(segments, z)], 1)
                        for z in (0.0, length)])
    f = []
    for j in range(segments):
        a, b = j, (j + 1) % segments
        f += [[a, b, a + segments], [b, b + segments, a + segments]]
    return TriMesh(v, np.array(f))


def test_a_straight_faceted_tube_keeps_its_creases():
    tube = prism(6)                                   # 60° between facets, flat elsewhere
    assert len(crease_edges(tube)) == 6


def test_a_coarse_curved_surface_has_no_creases():
    # 56° between the facets around, 39-45° between the bands: every edge bends, none stands out
    sphere = uv_sphere(6, 4)
    assert len(crease_edges(sphere, isolation_deg=None)) > 0
    assert len(crease_edges(sphere)) == 0
    # with the bands 26-32° apart, the 58° edges between them stand out again
    assert len(crease_edges(uv_sphere(6, 6))) > 0


def test_a_thin_plates_rim_keeps_its_creases():
    # a box 2 x 2 x 0.02: each side face spans both rims, its only other edge is flat
    v = np.array([[x, y, z] for z in (0.0, 0.02) for y in (0.0, 2.0) for x in (0.0, 2.0)])
    f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
    plate = TriMesh(v, f)
    assert len(crease_edges(plate)) == 12              # every edge of the box but the diagonals


def test_fewer_creases_hold_a_vertex_less():
    sphere = uv_sphere(6, 4)
    Q, W = vertex_quadrics(sphere)
    Qc, Wc = vertex_quadrics(sphere, isolation_deg=None)
    np.testing.assert_array_equal(W, Wc)
    Qf, _ = vertex_quadrics(sphere, crease_weight=0.0)
    np.testing.assert_allclose(Q, Qf)
    assert not np.allclose(Qc, Qf)
