"""Consistent winding of the reference (core.mesh.orient) and what a construction says of it."""
from __future__ import annotations

import numpy as np
import pytest

from core.mesh.trimesh import TriMesh
from core.mesh.orient import orient
from core.mesh.primitives import icosphere, torus


def _flipped(F: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return np.where(mask[:, None], F[:, ::-1], F)


@pytest.mark.parametrize("seed", range(4))
def test_randomly_flipped_faces_are_turned_back(seed):
    parts = [TriMesh(*icosphere(3)), TriMesh(*torus(24, 12))]
    V = np.concatenate([parts[0].vertices, parts[1].vertices + 5.0])
    F = np.concatenate([parts[0].faces, parts[1].faces + parts[0].n_vertices])
    mask = np.random.default_rng(seed).random(len(F)) < 0.4
    o = orient(TriMesh(V, _flipped(F, mask)))
    np.testing.assert_array_equal(o.mesh.faces, F)
    assert o.turned == mask.sum() and o.inconsistent_edges > 0
    assert "turned" in o.warnings()[0]


def test_clean_mesh_is_returned_as_it_is_and_inside_out_parts_turn():
    m = TriMesh(*icosphere(2))
    o = orient(m)
    assert o.mesh is m and o.turned == 0 and o.warnings() == []
    inside = orient(TriMesh(m.vertices, m.faces[:, ::-1]))
    np.testing.assert_array_equal(inside.mesh.faces, m.faces)
    assert inside.inside_out_parts == 1 and "inwards" in inside.warnings()[0]


@pytest.mark.parametrize("offset", [(2e5, -3e5, 1e4), (1e6, -1e6, 1e6)])
def test_a_closed_part_far_from_the_origin_keeps_facing_out(offset):
    """A closed part's signed volume, summed about the world's origin at 1e6, has terms of
    1e18 and rounds its sign away: taken about the part's own centre it is right."""
    m = TriMesh(*icosphere(3, radius=0.5))
    far = TriMesh(m.vertices + np.array(offset), m.faces)
    o = orient(far)
    assert o.mesh is far and o.turned == 0 and o.warnings() == []
    inside = orient(TriMesh(far.vertices, far.faces[:, ::-1]))
    np.testing.assert_array_equal(inside.mesh.faces, far.faces)


def test_open_part_keeps_the_majority_orientation():
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0.0]])
    F = np.array([[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]])
    o = orient(TriMesh(V, _flipped(F, np.array([False, False, True, False]))))
    np.testing.assert_array_equal(o.mesh.faces, F)
    assert o.turned == 1
