"""The base's edge splits where the reference strays furthest from it: topology and winding
kept, new vertices on the reference, nothing split where every face is alike, the furthest
faces split first, and the builder's report and scale-independence with them."""
import numpy as np
import pytest

from core.base.build import build_base
from core.base.refine import MAX_EXTRA, refine, thickness
from core.base.topology import topology
from core.spatial.closest import ClosestPointIndex
from core.mesh.trimesh import TriMesh
from core.mesh.primitives import holed_plate, icosphere, noisy_sphere, torus

from test_microtopology import directed_edge_check


def bumped_plate(n=24, height=0.3):
    """A flat square grid with one bump in a corner: the coarse base's faces over the bump
    are the ones far from it."""
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    z = height * np.exp(-((x - 0.25) ** 2 + (y - 0.25) ** 2) / 0.005)
    v = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    f = np.concatenate([np.stack([i, i + 1, i + n + 2], -1).reshape(-1, 3),
                        np.stack([i, i + n + 2, i + n + 1], -1).reshape(-1, 3)])
    return TriMesh(v, f)


@pytest.mark.parametrize("shape", ["torus", "plate3", "noisy"])
def test_splits_keep_topology_and_winding_and_land_on_the_reference(shape):
    v, f = {"torus": lambda: torus(40, 24), "plate3": lambda: holed_plate(3, 4),
            "noisy": lambda: noisy_sphere(4000, 0.08)}[shape]()
    ref = TriMesh(v, f)
    base = build_base(ref, ratio=0.1, max_error=0).mesh
    out, splits = refine(base, ref, 0.0)          # every face with any distance may split
    assert splits > 0
    assert out.n_faces == base.n_faces + 2 * splits <= base.n_faces * (1 + MAX_EXTRA) + 2
    assert topology(out).as_dict() == topology(base).as_dict()
    assert directed_edge_check(out.faces)[1] == 0          # manifold, consistently wound
    new = out.vertices[base.n_vertices:]
    _, _, d = ClosestPointIndex(ref.vertices, ref.faces).query(new)
    assert np.median(d) < 1e-9 * ref.bbox_diagonal + 1e-12


def test_nothing_split_where_every_face_is_alike():
    v, f = icosphere(5)
    ref = TriMesh(v, f)
    base = TriMesh(*icosphere(2))
    out, splits = refine(base, ref, 4.0)
    assert splits == 0 and out.n_faces == base.n_faces


def test_the_faces_furthest_from_the_reference_split_first():
    ref = bumped_plate()
    base = build_base(ref, ratio=0.2, max_error=0).mesh
    before = thickness(base, ref.vertices) * base.face_areas
    out, splits = refine(base, ref, 4.0)
    after = thickness(out, ref.vertices) * out.face_areas
    assert 0 < splits
    assert after.max() < before.max() and after.sum() < before.sum()
    # the splits sit around the bump, not on the flat part of the plate
    new = out.vertices[base.n_vertices:]
    assert np.all(np.linalg.norm(new[:, :2] - 0.25, axis=1) < 0.35)


def test_the_builder_reports_its_splits_and_keeps_a_face_count_asked_for():
    ref = TriMesh(*noisy_sphere(4000, 0.08))
    plain = build_base(ref, ratio=0.1, max_error=0)
    split = build_base(ref, ratio=0.1, max_error=0, refine=1.0)
    assert plain.report["splits"] == 0
    assert split.report["splits"] > 0
    assert split.report["faces"] == plain.report["faces"] + 2 * split.report["splits"]
    asked = build_base(ref, faces=300, max_error=0, refine=1.0)
    assert asked.report["splits"] == 0
    with pytest.raises(ValueError):
        build_base(ref, refine=-1.0)


@pytest.mark.parametrize("scale", [1e-4, 1e4])
def test_split_bases_are_the_same_at_any_scale(scale):
    ref = TriMesh(*torus(40, 24))
    one = build_base(ref, ratio=0.1, refine=1.0).mesh
    other = build_base(TriMesh(ref.vertices * scale, ref.faces), ratio=0.1, refine=1.0).mesh
    assert np.array_equal(one.faces, other.faces)
    np.testing.assert_allclose(other.vertices / scale, one.vertices, atol=1e-6)
