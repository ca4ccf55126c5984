"""Coincident vertices welded (core.mesh.weld) and the construction's reference welded."""
import numpy as np
import pytest

from core.mesh.reference import oriented_reference
from core.mesh.trimesh import MeshError, TriMesh
from core.mesh.primitives import noisy_sphere, torus
from core.mesh.weld import TOLERANCE, weld
from corpus import soup, with_degenerate


def _torus() -> TriMesh:
    return TriMesh(*torus(24, 16))


def test_a_soup_welds_back_into_the_mesh():
    mesh = _torus()
    w = weld(soup(mesh))
    assert (w.merged, w.dropped) == (3 * mesh.n_faces - mesh.n_vertices, 0)
    assert w.mesh.n_vertices == mesh.n_vertices and w.mesh.n_faces == mesh.n_faces
    assert w.mesh.n_components == 1 and w.mesh.genus == mesh.genus == 1
    assert not w.mesh.boundary_edges.size
    # the same triangles, each corner at the file's own position
    assert np.array_equal(w.mesh.vertices[w.mesh.faces], mesh.vertices[mesh.faces])


def test_within_the_tolerance_only():
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    step = TOLERANCE * np.sqrt(2)                       # of the two triangles' diagonal
    for shift, merged in ((0.4 * step, 2), (1.5 * step, 0)):
        other = np.array([[1, 0, 0], [0, 1, 0], [1, 1, 0]], float) + [shift, 0, 0]
        w = weld(TriMesh(np.vstack([tri, other]), np.array([[0, 1, 2], [4, 3, 5]])))
        assert w.merged == merged
        assert w.mesh.n_vertices == 6 - merged


def test_collapsed_faces_dropped_and_loose_vertices_left_alone():
    v, f = noisy_sphere(320)
    extra = np.vstack([v, v[:1] + 1e-9, [[9.0, 9.0, 9.0]]])     # a copy of vertex 0, a loose one
    sliver = np.array([[0, len(v), 5]])                           # collapses onto (0, 0, 5)
    w = weld(TriMesh(extra, np.vstack([f, sliver])))
    assert (w.merged, w.dropped) == (1, 1)
    assert w.mesh.n_faces == len(f) and w.mesh.n_vertices == len(v) + 1
    assert np.array_equal(w.mesh.vertices[-1], [9.0, 9.0, 9.0])
    assert "1 coincident vertices" in w.warning() and "1 faces that collapsed" in w.warning()


def test_nothing_to_weld_is_the_mesh_itself():
    mesh = _torus()
    w = weld(mesh)
    assert w.mesh is mesh and w.merged == 0 and w.warning() is None


def test_every_face_collapsing_is_refused():
    v = np.array([[0, 0, 0], [1e-12, 0, 0], [0, 1e-12, 0], [5, 5, 5]], float)
    with pytest.raises(MeshError, match="three distinct vertices"):
        weld(TriMesh(v, np.array([[0, 1, 2]])), tolerance=1.0)


def test_the_construction_welds_its_reference_and_says_so():
    mesh = _torus()
    messy = with_degenerate(soup(mesh))
    ref, warnings = oriented_reference(messy)
    assert ref.n_components == 1 and ref.genus == 1 and not ref.boundary_edges.size
    assert ref.n_faces == mesh.n_faces and ref.n_vertices == mesh.n_vertices
    assert any("coincident vertices" in w and "were welded" in w for w in warnings)
    extra = messy.n_faces - mesh.n_faces         # half repeat a vertex, half lie on a line
    assert warnings[0].endswith(f"were welded, and {extra // 2} faces that collapsed were left "
                                "out")
    assert warnings[1] == f"{extra - extra // 2} faces of no area (degenerate) were left out"
