"""The base's edge flips toward the reference: a quad cut across a ridge is flipped onto it,
nothing moves where the base lies on the reference, the shapes, the topology and the winding
are kept, and the exact distance to one's own triangle that the gains use."""
import numpy as np

from core.base.build import build_base
from core.base.decimate import decimate
from core.base.surface_flips import QUALITY_SLACK, surface_flips
from core.base.topology import topology
from core.spatial.closest import ClosestPointIndex
from core.mesh.trimesh import TriMesh
from core.micro.metrics import triangle_isotropy
from core.spatial.point_triangle import pair_distances
from core.mesh.primitives import noisy_sphere

from test_microtopology import directed_edge_check


def roof(n, height=0.5, size=4.0):
    """A square grid of n x n cells on [0, size]², each cell split along its main diagonal,
    lifted onto a roof whose ridge runs along the other diagonal of the square (x + y =
    size): the cells the ridge crosses are cut across it."""
    t = np.linspace(0.0, size, n + 1)
    x, y = np.meshgrid(t, t, indexing="ij")
    z = height * (1.0 - np.abs(x + y - size) / (size / 2))
    v = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    f = np.concatenate([np.stack([i, i + n + 2, i + 1], 1), np.stack([i, i + n + 1, i + n + 2], 1)])
    return TriMesh(v, f)


def _distances(base: TriMesh, ref: TriMesh) -> np.ndarray:
    return ClosestPointIndex(base.vertices, base.faces).query(ref.vertices)[2]


def test_the_quads_cut_across_a_ridge_are_flipped_onto_it():
    base, ref = roof(4), roof(40)
    assert _distances(base, ref).max() > 0.1
    out, flips = surface_flips(base, ref, 0.4)
    assert flips == 4                                 # the four cells the ridge crosses
    assert _distances(out, ref).max() < 1e-9          # the roof exactly
    assert np.array_equal(out.vertices, base.vertices) and out.n_faces == base.n_faces
    assert topology(out).as_dict() == topology(base).as_dict()
    assert directed_edge_check(out.faces) == directed_edge_check(base.faces)


def test_nothing_flips_where_the_base_lies_on_the_reference():
    ref = TriMesh(*noisy_sphere(3000, 0.08))
    out, flips = surface_flips(ref, ref, 0.0)
    assert flips == 0 and np.array_equal(out.faces, ref.faces)


def test_flips_bring_the_base_closer_and_keep_shapes_topology_and_winding():
    ref = TriMesh(*noisy_sphere(6000, 0.08))
    dec = decimate(ref, int(0.08 * ref.n_faces))      # the collapses alone: no flips yet
    base = TriMesh(dec.vertices, dec.faces)
    out, flips = surface_flips(base, ref, 0.4)
    assert flips > 0
    w = ref.vertex_areas
    assert (w * _distances(out, ref)).sum() < (w * _distances(base, ref)).sum()
    assert topology(out).as_dict() == topology(base).as_dict()
    assert directed_edge_check(out.faces)[1] == 0
    old = {tuple(sorted(f)) for f in base.faces.tolist()}
    new = np.array([f for f in out.faces.tolist() if tuple(sorted(f)) not in old])
    assert len(new) == 2 * flips
    q_new = triangle_isotropy(out.vertices, new)[0]
    assert q_new.min() >= 0.4
    # no flip lowers the worse triangle of its quad by more than the slack
    q_base = triangle_isotropy(base.vertices, base.faces)[0]
    assert q_new.min() >= q_base.min() - QUALITY_SLACK


def test_the_builder_reports_its_surface_flips():
    ref = TriMesh(*noisy_sphere(6000, 0.08))
    rep = build_base(ref, ratio=0.08, max_error=0).report
    assert rep["surface_flips"] > 0
    assert rep["topology_base"] == rep["topology_input"]


def test_pair_distances_are_each_points_distance_to_its_own_triangle():
    rng = np.random.default_rng(3)
    n = 60
    A, B, C = (rng.normal(size=(n, 3)) for _ in range(3))
    C[:10] = A[:10] + 0.5 * (B[:10] - A[:10])        # collinear: segments
    B[10:15] = A[10:15]                               # repeated corners
    P = rng.normal(size=(n, 3)) * 2
    d = pair_distances(P, A, B, C)
    for k in range(n):
        tri = np.stack([A[k], B[k], C[k]])
        want = ClosestPointIndex(tri, np.array([[0, 1, 2]])).query(P[k:k + 1])[2][0]
        assert abs(d[k] - want) < 1e-12


def test_the_gains_measured_in_blocks_are_the_same(monkeypatch):
    import core.base.surface_flips as flips
    ref = TriMesh(*noisy_sphere(6000, 0.08))
    dec = decimate(ref, int(0.08 * ref.n_faces))
    base = TriMesh(dec.vertices, dec.faces)
    whole, n = surface_flips(base, ref, 0.4)
    monkeypatch.setattr(flips, "BLOCK", 7)               # a few quads at a time
    blocks, m = flips.surface_flips(base, ref, 0.4)
    assert n == m > 0 and np.array_equal(whole.faces, blocks.faces)
