"""Levels across non-manifold edges (three or more faces on one edge): every stage that sets
levels keeps all the faces of such an edge within one level (``core.micro.levels``, the one
definition), the budget counts what the tessellation has there, and a construction on a
sphere with fins glued onto its edges and holes cut into it ends crack-free (issue 47)."""
from types import SimpleNamespace

import numpy as np
import pytest

from core.mesh import primitives
from core.construct import construct
from core.construct.choose_levels import fill_budget, residual_exchange
from core.lod import effective_micro_triangles, exchange_to_budget, roll_back_to_budget
from core.lod.expansion import expansion_levels
from core.mesh.trimesh import TriMesh
from core.micro.levels import balance_levels, edge_flags, edge_min_max, is_balanced
from core.micro.metrics import crack_edges
from core.micro.micromesh import MicroMesh
from core.settings.fields import preset

A, B, C, D = range(4)


def book(far: float = 1.0) -> TriMesh:
    """Three pages A, B, C on the edge (0, 1), and D on C's edge (1, 4): A and D share no
    edge. ``far`` moves A's apex out (A's area grows with it)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, far, 0], [0.5, -1, 0], [0.5, 0, 1], [1, 0.5, 1.5]])
    return TriMesh(v, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4], [4, 1, 5]]))


def total(lv):
    return float(np.sum(lv))


def micro_edge_uses(mm: MicroMesh) -> np.ndarray:
    """How many non-degenerate micro-triangles use each micro-edge."""
    t = mm.tessellate().triangles
    t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 2] != t[:, 0])]
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)[1]


def assert_stitched(mm: MicroMesh) -> None:
    """No crack, and each non-manifold base edge's micro-edges are shared by all its faces."""
    base, lv = mm.base, mm.levels
    emin, _ = edge_min_max(base, lv)
    nm, bd = base.nonmanifold_edges, base.boundary_edges
    tess = mm.tessellate()
    t = tess.triangles
    t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 2] != t[:, 0])]
    assert effective_micro_triangles(lv, base) == len(t)
    assert crack_edges(tess.triangles, tess.vertices, int(np.sum(2 ** emin[bd]))) == 0
    uses = micro_edge_uses(mm)
    assert (uses >= 3).sum() == np.sum(2 ** emin[nm]) and set(uses) <= {1, 2, 3}


def test_balance_counts_every_face_of_a_nonmanifold_edge():
    m = book()
    assert len(m.nonmanifold_edges) == 1 and (m.face_adjacency[A] == -1).all()
    assert not is_balanced(m, [2, 1, 0, 0])                      # A and C: two apart
    np.testing.assert_array_equal(balance_levels(m, [2, 0, 0, 0]), [2, 1, 1, 0])
    assert edge_flags(m, [2, 1, 1, 0]).tolist() == [1, 0, 2, 0]  # A: edge 0, C: edge 1
    assert_stitched(MicroMesh.flat(m, [2, 1, 1, 1]))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_levels_on_a_finned_sphere_are_stitched(seed):
    m = TriMesh(*primitives.finned_sphere(320, fins=8, holes=6, seed=seed))
    assert len(m.nonmanifold_edges) == 8 and len(m.boundary_edges) > 0
    lv = balance_levels(m, np.random.default_rng(seed).integers(0, 4, m.n_faces))
    assert is_balanced(m, lv)
    assert_stitched(MicroMesh.flat(m, lv))


def test_exchange_to_budget_never_pairs_an_up_with_a_down_across_a_nonmanifold_edge():
    """A's up is paid by a down: C (the least useful) shares the non-manifold edge with A,
    so D goes down instead."""
    m = book()
    lv = np.full(4, 2)
    e_prev, e_now = np.ones(4), np.array([0.4, 0.9, 0.999, 0.99])
    e_prev[A] = 10.0
    e_now[A] = 4.0
    out = exchange_to_budget(lv, 2, e_prev, e_now, m, total, total(lv), 1)
    assert is_balanced(m, out) and total(out) <= total(lv)
    assert out.tolist() == [3, 2, 2, 1]


def test_roll_back_to_budget_keeps_nonmanifold_edges_balanced():
    m = book()
    lv = np.array([3, 3, 3, 2])
    gains = {3: np.array([0.1, 0.3, 0.2, 0.0]), 2: np.zeros(4)}
    out = roll_back_to_budget(lv, gains, m, total, 9.0)
    assert is_balanced(m, out) and total(out) <= 9.0
    assert out[B] == 3                                 # the most useful face kept its level


def test_fill_budget_raises_no_face_above_a_nonmanifold_neighbour():
    """A has no manifold neighbour below it, but B and C lie below it on its edge."""
    m = book()
    run = SimpleNamespace(base=m, s=SimpleNamespace(max_level=4), gains={}, cost=total,
                          budget=100.0)
    out = fill_budget(run, np.array([1, 0, 0, 0]))
    assert is_balanced(m, out)
    assert out.tolist() == [1, 1, 1, 1]


def test_residual_exchange_takes_its_downs_off_nonmanifold_edges():
    """A goes up; C has the smallest residual but lies on A's edge: D goes down instead."""
    m = book()
    run = SimpleNamespace(s=preset("default", residual_lod=0.25), base=m, cost=total,
                          budget=4.0)
    out = residual_exchange(run, np.ones(4, np.int64), np.array([1.0, 0.5, 1e-3, 1e-2]))
    assert is_balanced(m, out) and total(out) <= 4.0
    assert out.tolist() == [2, 1, 1, 0]


def test_expansion_levels_are_balanced_across_nonmanifold_edges():
    m = book(far=40.0)                                 # A 40 times the others' area
    lv = expansion_levels(m, 64 * 4, 2.0)
    emin, emax = edge_min_max(m, lv)
    assert (emax - emin <= 1).all() and lv[A] - lv[D] == 2
    assert lv.tolist() == [4, 3, 3, 2]


@pytest.mark.slow
def test_construction_on_a_finned_sphere_is_balanced_and_crack_free():
    """The reported crash: the residual exchange moved a face down beside a finer face on a
    fin's edge (``with_levels needs balanced levels``)."""
    ref = TriMesh(*primitives.finned_sphere(2000, fins=40, holes=60))
    s = preset("fast", iterations=10, subdivide_at=(3, 8), max_level=2, views_per_iter=3,
               train_resolution=64, lod_resolution=48, eval_resolution=64, eval_views=4,
               geom_error=False, polish_steps=0, lp_bounds=False)
    r = construct(ref, None, None, s)
    mm = r.micromesh
    assert len(mm.base.nonmanifold_edges) == 40
    note = r.metrics["residual_lod"]
    assert note["faces_up"] > 0 and note["faces_down"] > 0
    assert is_balanced(mm.base, mm.levels) and len(set(mm.levels)) > 1
    assert r.metrics["cracks"] == 0
    assert_stitched(mm)
