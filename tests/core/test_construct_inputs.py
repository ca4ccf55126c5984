"""The construction's reading of its input (``core.construct.frame``): many parts said, seams
split in a file not counted as parts, loose vertices, repeated faces and two-face flaps left
out."""
import numpy as np

from core.mesh.trimesh import TriMesh
from tests.core.test_construct import icosphere


def test_many_parts_are_said():
    """From core.mesh.reference.MANY_PARTS connected components on, the run says what they
    cost; fewer parts get no warning."""
    from core.mesh.reference import MANY_PARTS, oriented_reference

    v, f = icosphere(1)

    def parts(n):
        return TriMesh(np.vstack([v * 0.1 + [k, 0, 0] for k in range(n)]),
                       np.vstack([f + k * len(v) for k in range(n)]))

    _, few = oriented_reference(parts(MANY_PARTS - 1))
    _, many = oriented_reference(parts(MANY_PARTS))
    assert few == []
    assert many == [f"the input has {MANY_PARTS} separate parts: the base keeps every one, so "
                    "small parts take base triangles and budget from the large ones"]


def test_seams_split_in_a_file_are_not_parts():
    """A sphere whose vertices are split along every face (as files split them at UV seams or
    flat-shaded edges) is one part: welded (and said), no many-parts warning."""
    from core.mesh.reference import oriented_reference

    v, f = icosphere(2)
    split = TriMesh(v[f.reshape(-1)], np.arange(3 * len(f)).reshape(-1, 3))
    assert split.n_components == len(f)
    assert oriented_reference(split)[1] == [f"{3 * len(f) - len(v)} coincident vertices (within "
                                            "1e-06 of the bounding-box diagonal) were welded"]


def test_loose_vertices_and_repeated_faces_are_left_out():
    """A stray vertex far away (a loose vertex or edge) would shrink the object in the unit
    frame, and repeated faces make edges look non-manifold: both are left out and said, and
    what remains is the clean mesh, so the construction is the clean mesh's."""
    from core.mesh.reference import oriented_reference

    v, f = icosphere(2)
    far = np.vstack([v[:5], [[100.0, 0, 0], [100.0, 1, 0]], v[5:]])      # two loose vertices
    remap = np.where(f >= 5, f + 2, f)
    messy = TriMesh(far, np.vstack([remap, np.roll(remap[:3], 1, 1), remap[7:8]]))
    got, warnings = oriented_reference(messy)
    clean, none = oriented_reference(TriMesh(v, f))
    assert none == []
    assert warnings == ["2 vertices in no face (loose vertices or edges) were left out",
                        "4 repeated faces (the same three vertices again) were left out"]
    np.testing.assert_array_equal(got.vertices, clean.vertices)
    np.testing.assert_array_equal(got.faces, clean.faces)


def test_a_flap_of_two_faces_wound_both_ways_is_left_out():
    """A triangle hanging on one edge of the surface, once each way round (a sheet of no
    thickness, as in the beast scan): both copies go, and the surface is manifold again."""
    from core.mesh.reference import oriented_reference

    v, f = icosphere(2)
    a, b = f[0, 0], f[0, 1]
    tip = len(v)
    flap = np.array([[a, b, tip], [b, a, tip]])
    messy = TriMesh(np.vstack([v, [[0.0, 0.0, 3.0]]]), np.vstack([f, flap]))
    assert len(messy.nonmanifold_edges) == 1
    got, warnings = oriented_reference(messy)
    assert warnings == ["2 faces with a copy wound the other way (sheets of no thickness) were "
                        "left out"]
    assert got.n_faces == len(f) and got.is_closed_manifold and len(got.nonmanifold_edges) == 0
