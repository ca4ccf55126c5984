"""Adaptive LOD: criteria, the one-ring rules of Algorithms 1 and 2, ±1 balance, budgets."""
import numpy as np
import pytest

from core.lod import (LodError, chamfer_face_errors, effective_micro_triangles, face_error_sums,
                      in_optimization_lod, micro_triangle_count, post_process_lod, relative_gain,
                      roll_back_to_budget, trim_to_budget)
from core.mesh.trimesh import TriMesh
from core.micro.micromesh import MicroMesh
from core.micro.levels import balance_levels, is_balanced


def _grid(n=6):
    """An n×n quad grid split into 2n² triangles (a plane patch with interior one-rings)."""
    xs, ys = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    v = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1).astype(float)
    f = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = i * (n + 1) + j, (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1, i * (n + 1) + j + 1
            f += [[a, b, c], [a, c, d]]
    return TriMesh(v, np.array(f))


def test_face_error_sums_and_gain():
    tri_face = np.array([0, 0, 1, 2])
    tid = np.array([[[-1, 0, 1], [2, 3, 3]]])
    err = np.array([[[9.0, 1.0, 2.0], [4.0, 0.5, 0.5]]])
    assert face_error_sums(err, tid, tri_face, 4).tolist() == [3.0, 4.0, 1.0, 0.0]
    g = relative_gain(np.array([4.0, 2.0, 0.0]), np.array([1.0, 2.0, 0.0]))
    assert g.tolist() == [0.75, 0.0, 0.0]
    with pytest.raises(LodError):
        face_error_sums(err, tid[:, :1], tri_face, 4)


def test_algorithm1_below_min_level_subdivides_all():
    m = _grid()
    lv = in_optimization_lod(np.zeros(m.n_faces, int), 0, 1, None, m.face_neighbors_csr)
    assert (lv == 1).all()


def test_algorithm1_one_ring_rule():
    m = _grid()
    ring = m.face_neighbors_csr
    lv = np.full(m.n_faces, 2)
    stopped = 20
    lv[stopped] = 1                                   # stopped at the previous level
    gains = np.full(m.n_faces, 0.5)
    gains[3] = 0.05                                   # below τ = 0.1
    out = in_optimization_lod(lv, 2, 1, gains, ring)
    ptr, idx = ring
    neighbours = set(idx[ptr[stopped]:ptr[stopped + 1]].tolist())
    for f in range(m.n_faces):
        if f == stopped:
            assert out[f] == 1
        elif f in neighbours or f == 3:
            assert out[f] == 2, f
        else:
            assert out[f] == 3, f
    assert is_balanced(m, out)
    with pytest.raises(LodError):
        in_optimization_lod(lv, 2, 1, None, ring)


def test_algorithm2_rollback_and_one_ring_rule():
    m = _grid()
    ring = m.face_neighbors_csr
    n = m.n_faces
    keep = 30                                          # important face: large gains everywhere
    g = {l: np.full(n, 0.01) for l in range(1, 5)}
    for l in g:
        g[l][keep] = 0.5
    out = post_process_lod(g, 4, 1, ring)
    ptr, idx = ring
    nb = idx[ptr[keep]:ptr[keep + 1]]
    assert out[keep] == 4
    assert (out[nb] == 3).all()                        # rolled back once, then blocked
    others = np.setdiff1d(np.arange(n), np.concatenate([nb, [keep]]))
    # Faces next to the blocked ring stop at 2; far faces go down to ℓmin = 1.
    assert out[others].min() == 1 and out[others].max() <= 2
    assert is_balanced(m, out)
    # Everything useless: all the way to ℓmin.
    flat = post_process_lod({l: np.zeros(n) for l in range(1, 5)}, 4, 1, ring)
    assert (flat == 1).all()


def test_budget_trim_keeps_best_and_balance():
    m = _grid()
    ring = m.face_neighbors_csr
    old = np.full(m.n_faces, 1)
    gains = np.linspace(0.2, 1.0, m.n_faces)
    new = in_optimization_lod(old, 1, 1, gains, ring)
    assert (new == 2).all()
    budget = micro_triangle_count(old) + (16 - 4) * 10  # room for 10 subdivisions
    out = trim_to_budget(old, new, gains, micro_triangle_count, budget)
    assert micro_triangle_count(out) <= budget
    assert (out == 2).sum() == 10
    assert set(np.flatnonzero(out == 2)) == set(np.argsort(-gains)[:10])
    assert is_balanced(m, out)


def test_roll_back_to_budget():
    m = _grid()
    lv = np.full(m.n_faces, 3)
    gains = {3: np.linspace(0, 1, m.n_faces), 2: np.linspace(0, 1, m.n_faces)}
    budget = 0.6 * micro_triangle_count(lv)
    out = roll_back_to_budget(lv, gains, m, micro_triangle_count, budget)
    assert micro_triangle_count(out) <= budget
    assert is_balanced(m, out)
    assert out[np.argmax(gains[3])] == 3              # the most useful face kept its level


def test_chamfer_face_errors():
    mv = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1.0], [1, 0, 1.0]])
    mf = np.array([0, 0, 1, 1])
    ref = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1.5], [1, 0, 1.5]])
    e = chamfer_face_errors(mv, mf, ref, 2)
    assert e[0] == pytest.approx(0.0)
    assert e[1] == pytest.approx(1.0)                  # 0.5 one way + 0.5 the other


def test_exchange_to_budget_moves_triangles_to_where_they_help():
    from core.lod import exchange_to_budget
    m = _grid()
    n = m.n_faces
    lv = np.full(n, 2)
    budget = micro_triangle_count(lv)                  # binding: uniform level 2 exactly
    e_prev = np.full(n, 1.0)
    e_now = np.full(n, 0.99)                           # level 2 barely helped almost everywhere
    hot = np.array([10, 11, 40, 41])
    e_prev[hot], e_now[hot] = 10.0, 4.0                # ... but a lot here
    out = exchange_to_budget(lv, 2, e_prev, e_now, m, micro_triangle_count, budget, 1)
    assert micro_triangle_count(out) <= budget
    assert is_balanced(m, out)
    assert (out[hot] == 3).all()
    assert (out == 1).sum() >= 4 * len(hot)
    # Nothing worth paying for: unchanged.
    same = exchange_to_budget(lv, 2, np.ones(n), np.ones(n), m, micro_triangle_count, budget, 1)
    assert np.array_equal(same, lv)
    # Already over the budget with nothing to trade: unchanged (it raised on an empty cut).
    over = exchange_to_budget(lv, 2, np.ones(n), np.ones(n), m,
                              micro_triangle_count, budget - 1, 1)
    assert np.array_equal(over, lv)


def test_exchange_to_budget_pairs_ups_and_downs_in_the_budgets_own_unit():
    """In bytes (micromesh-tools' formula) a level up from 2 costs 40 bytes and a level down
    saves 12: the exchange pays for each up with as many downs as that takes."""
    from core.lod import exchange_to_budget
    from core.micro.metrics import mmt_formula_bytes
    m = _grid()
    n = m.n_faces

    def cost(lv):
        return mmt_formula_bytes(lv, m.n_vertices)

    lv = np.full(n, 2)
    budget = cost(lv)
    e_prev, e_now = np.full(n, 1.0), np.full(n, 0.99)
    hot = np.array([10, 11, 40, 41])
    e_prev[hot], e_now[hot] = 10.0, 4.0
    out = exchange_to_budget(lv, 2, e_prev, e_now, m, cost, budget, 1)
    assert cost(out) <= budget and is_balanced(m, out)
    assert (out[hot] == 3).all()
    assert (out == 1).sum() >= 3 * len(hot)           # 40 / 12 bytes: at least 3 downs each


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_effective_count_is_the_tessellations(seed):
    """The budget counts the micro-triangles the crack-free tessellation really has."""
    m = _grid(5)
    lv = balance_levels(m, np.random.default_rng(seed).integers(0, 5, m.n_faces))
    t = MicroMesh.flat(m, lv).tessellate().triangles
    real = int(((t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 2] != t[:, 0])).sum())
    assert effective_micro_triangles(lv, m) == real
    assert real < micro_triangle_count(lv)
