"""The base builder's crease planes: they hold a short edge between large faces as firmly as
those faces hold their planes, keep their edge length² where that is more, and sit only on
edges sharper than the feature angle."""
import numpy as np
import pytest

from core.base.quadrics import CREASE_AREA, quadric_error, vertex_quadrics
from core.mesh import TriMesh


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
