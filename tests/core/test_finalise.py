"""The end of a construction (``core.construct.fitting`` and ``choose_levels``) on stand-in
runs: the residual exchange of levels, kept only where it lowers the shading error, and the
base round, kept only where it helps."""
import time

import numpy as np
import pytest

from core.construct.losses import mean_edge_length
from core.mesh.trimesh import TriMesh
from core.settings.fields import preset
from tests.core.test_construct import icosphere


def test_residual_exchange_moves_levels_to_where_the_fit_misses():
    """Faces with large fit residuals go up, quiet ones go down, the budget and the ±1 rule
    hold (core.construct.choose_levels.residual_exchange)."""
    from types import SimpleNamespace

    from core.construct.choose_levels import residual_exchange
    from core.lod import effective_micro_triangles
    from core.micro.levels import is_balanced

    v, f = icosphere(2)
    base = TriMesh(v, f)
    levels = np.full(base.n_faces, 2)
    cost = lambda lv: effective_micro_triangles(lv, base)  # noqa: E731
    run = SimpleNamespace(s=preset("default", residual_lod=0.15), base=base, cost=cost,
                          budget=cost(levels))
    E = np.full(base.n_faces, 1e-6)
    hot = np.flatnonzero(base.vertices[base.faces].mean(1)[:, 2] > 0.8)
    E[hot] = 1.0
    new = residual_exchange(run, levels, E)
    assert cost(new) <= run.budget and is_balanced(base, new)
    assert (new[hot] == 3).all() and (new < 2).any()
    run.s = preset("default", residual_lod=0.0)
    np.testing.assert_array_equal(residual_exchange(run, levels, E), levels)


@pytest.mark.parametrize("min_level", [0, 1])
def test_quiet_faces_go_down_to_min_level(min_level):
    """The default preset lets the exchange take faces the fit already matches down to level 0
    (min_level 0); with min_level 1 (the paper's) none goes below 1."""
    from types import SimpleNamespace

    from core.construct.choose_levels import residual_exchange
    from core.lod import effective_micro_triangles
    from core.micro.levels import is_balanced

    assert preset("default").min_level == 0 and preset("paper").min_level == 1
    v, f = icosphere(2)
    base = TriMesh(v, f)
    levels = np.full(base.n_faces, 1)
    cost = lambda lv: effective_micro_triangles(lv, base)  # noqa: E731
    run = SimpleNamespace(s=preset("default", min_level=min_level), base=base, cost=cost,
                          budget=cost(levels))
    E = np.full(base.n_faces, 1e-6)
    hot = np.flatnonzero(base.vertices[base.faces].mean(1)[:, 2] > 0.8)
    E[hot] = 1.0
    new = residual_exchange(run, levels, E)
    assert cost(new) <= run.budget and is_balanced(base, new) and new.min() == min_level
    assert (new[hot] == 2).all() if min_level == 0 else np.array_equal(new, levels)


@pytest.mark.parametrize("hot_cap", [False, True])
def test_moved_levels_are_kept_only_where_they_lower_the_shading_error(hot_cap, monkeypatch):
    """fitting.fitted: the levels residual_exchange moves are fitted again and kept only when
    the shading error of the same reference samples falls; otherwise the first fit stays.
    Detail on one cap of a sphere: moving levels there helps (kept). Moving levels onto a
    smooth cap while the detailed one loses them hurts (refused). The exchange is given each
    face's share of the distance error plus its share of the shading error."""
    from types import SimpleNamespace

    import core.construct.fitting as fin
    from core.fit import fit_samples, surface_errors
    from core.lod import effective_micro_triangles
    from core.micro.metrics import PhaseTimer
    from core.micro.micromesh import MicroMesh

    v, f = icosphere(2)
    base = TriMesh(v, f)
    rv, rf = icosphere(5)
    bumps = 1 + 0.03 * np.sin(40 * rv[:, 0]) * np.sin(40 * rv[:, 1]) * (rv[:, 2] > 0.3)
    ref = TriMesh(rv * bumps[:, None], rf)
    levels = np.full(base.n_faces, 2)
    mm = MicroMesh.flat(base, levels)
    cost = lambda lv: effective_micro_triangles(lv, base)  # noqa: E731
    run = SimpleNamespace(s=preset("default"), base=base, cost=cost, budget=cost(levels),
                          fixed=None, held_in_fit=None, scene=SimpleNamespace(ref=ref),
                          timer=PhaseTimer(),
                          notes={}, check_stop=lambda: None, deadline=np.inf,
                          announce=lambda phase: None,
                          h=mean_edge_length(base.vertices, base.faces))
    z = base.vertices[base.faces].mean(1)[:, 2]
    if hot_cap:       # the exchange as it should go: up where the detail is
        up, down = z > 0.5, z < -0.5
    else:             # the wrong way round: up on the smooth cap, down on the detail
        up, down = z < -0.5, z > 0.5
    wanted = np.where(up, 3, np.where(down, 1, levels))
    seen = {}
    measured = fin.surface_errors

    def errors(*args):
        out = measured(*args)
        seen.setdefault("errors", out)     # the first: the exchange's
        return out

    def exchange(run, lv, E):
        seen["E"] = E
        return wanted
    monkeypatch.setattr(fin, "surface_errors", errors)
    monkeypatch.setattr(fin, "residual_exchange", exchange)
    out, *_ = fin.fitted(run, mm)
    dist, normal = seen["errors"]    # each face's share of both errors, weighed alike
    np.testing.assert_allclose(seen["E"], dist / dist.sum() + normal / normal.sum())
    note = run.notes["residual_lod"]
    assert note["kept"] is hot_cap
    assert (note["shading_error_after"] < note["shading_error_before"]) is hot_cap
    np.testing.assert_array_equal(out.levels, wanted if hot_cap else levels)
    if not hot_cap:   # the base round starts from the same micro-mesh: its error is reused
        assert run.notes["base_fit"]["shading_error_before"] == note["shading_error_before"]
    samples = fit_samples(mm, ref)
    first = surface_errors(fin.fitted(SimpleNamespace(**{**vars(run), "cost": None}), mm)[0],
                           samples)[1].sum()
    assert surface_errors(out, samples)[1].sum() <= first * (1 + 1e-9)  # never worse
    # past the time limit's deadline the exchange is left out, and the notes say so
    late = SimpleNamespace(**{**vars(run), "deadline": 0.0, "notes": {}})
    out, *_ = fin.fitted(late, mm)
    assert late.notes["residual_lod"] == {"kept": False, "cut_by_time_limit": True}
    np.testing.assert_array_equal(out.levels, levels)


@pytest.mark.parametrize("growth", [1.1, 0.0])
def test_the_base_and_the_directions_move_only_where_it_helps(growth, monkeypatch):
    """fitting.fitted's last rounds move the base vertices, then turn the directions, five
    times; each is kept where the shading error falls and the shell stays within a tenth of
    where it was before them (here: a bumpy sphere, kept, the later passes lowering the
    error further unless the time limit is over), else the displacements-only fit stays
    (forced by allowing no shell at all); without ``fit_directions`` the directions are not
    touched."""
    from types import SimpleNamespace

    import core.construct.fitting as fin
    from core.micro.metrics import PhaseTimer
    from core.micro.micromesh import MicroMesh

    v, f = icosphere(2)
    base = TriMesh(v, f)
    rv, rf = icosphere(5)
    ref = TriMesh(rv * (1 + 0.03 * np.sin(9 * rv[:, :1]) * np.sin(7 * rv[:, 1:2])), rf)
    mm = MicroMesh.flat(base, np.full(base.n_faces, 2))
    run = SimpleNamespace(s=preset("default", residual_lod=0.0), base=base, cost=None, budget=0,
                          fixed=None, held_in_fit=None, scene=SimpleNamespace(ref=ref),
                          timer=PhaseTimer(),
                          notes={}, check_stop=lambda: None, deadline=np.inf,
                          announce=lambda phase: None,
                          h=mean_edge_length(base.vertices, base.faces))
    monkeypatch.setattr(fin, "_SHELL_GROWTH", growth)
    out, _, error = fin.fitted(run, mm)
    note = run.notes["base_fit"]
    assert note["kept"] is (growth > 0)
    assert note["passes_kept"] >= 2 if growth > 0 else note["passes_kept"] == 0  # of five
    assert (note["shading_error_after"] < note["shading_error_before"]) is (growth > 0)
    moved = np.abs(out.base.vertices - base.vertices).max()
    assert bool(moved > 0) is (growth > 0)
    turn = run.notes["direction_fit"]
    assert turn["kept"] is (growth > 0)
    assert (turn["shading_error_after"] < turn["shading_error_before"]) is (growth > 0)
    assert bool(np.abs(out.directions - mm.directions).max() > 0) is (growth > 0)
    if growth > 0:     # the later passes lower the shading error further...
        run.s, run.notes = preset("default", residual_lod=0.0, fit_passes=1), {}
        _, _, once = fin.fitted(run, mm)
        assert run.notes["base_fit"]["passes_kept"] == 1 and error < once
        # ...unless the time limit is over: then only the passes that end before it (here
        # none: the base stays), and the notes say why
        run.s, run.notes, run.deadline = preset("default", residual_lod=0.0), {}, 0.0
        late, _, _ = fin.fitted(run, mm)
        assert run.notes["fit_passes"] == {"done": 0, "cut_by_time_limit": True}
        np.testing.assert_array_equal(late.base.vertices, mm.base.vertices)
        assert "base_fit" not in run.notes
        run.deadline = np.inf
    run.s, run.notes = preset("default", residual_lod=0.0, fit_directions=False), {}
    out, *_ = fin.fitted(run, mm)
    assert "direction_fit" not in run.notes
    np.testing.assert_array_equal(out.directions, mm.directions)


@pytest.mark.parametrize("tail", [0.0, 1e6])
def test_an_optional_fit_stage_leaves_room_for_the_bounds_after_it(tail, monkeypatch):
    """The residual exchange and the moving passes run only where they would end before the
    deadline with the bounds' tries (``_TAIL_TIME`` times the first fit) still to come."""
    from types import SimpleNamespace

    import core.construct.fitting as fin
    from core.micro.metrics import PhaseTimer
    from core.micro.micromesh import MicroMesh

    v, f = icosphere(1)
    base = TriMesh(v, f)
    rv, rf = icosphere(3)
    mm = MicroMesh.flat(base, np.full(base.n_faces, 1))
    run = SimpleNamespace(s=preset("default", residual_lod=0.0, fit_passes=1), base=base,
                          cost=None, budget=0, fixed=None, held_in_fit=None,
                          scene=SimpleNamespace(ref=TriMesh(rv * 1.02, rf)), timer=PhaseTimer(),
                          notes={}, check_stop=lambda: None,
                          deadline=time.perf_counter() + 600.0, announce=lambda phase: None,
                          h=mean_edge_length(base.vertices, base.faces))
    monkeypatch.setattr(fin, "_PASS_TIME", 0.0)
    monkeypatch.setattr(fin, "_TAIL_TIME", tail)
    fin.fitted(run, mm)
    if tail:
        assert run.notes["fit_passes"] == {"done": 0, "cut_by_time_limit": True}
        assert "base_fit" not in run.notes
    else:
        assert "fit_passes" not in run.notes and "base_fit" in run.notes


def test_a_base_vertex_whose_shell_the_base_round_thickens_is_put_back(monkeypatch):
    """fitting._base_moved: where the base round thickens a vertex's shell past twice what it
    was (here: one vertex pulled far out, its star's values following it), that vertex goes
    back where it was (with the neighbours whose values it shared, thickened too) and the
    displacements are fitted again around it; the other vertices keep their moves.
    ``run.notes`` counts the vertices put back per round; held vertices are fixed in the
    round itself."""
    from types import SimpleNamespace

    import core.construct.fitting as fin
    from core.micro.metrics import PhaseTimer
    from core.micro.micromesh import MicroMesh

    v, f = icosphere(2)
    base = TriMesh(v, f)
    mm = MicroMesh.flat(base, np.full(base.n_faces, 2), v.copy())
    mm = mm.with_displacements(0.01 * np.sin(7 * mm.micro_vertex_base_positions()[:, 0]))
    pulled, far = 0, int(np.argmin(v @ v[0]))              # far: the opposite pole
    calls = []

    def fake_fit(run, m, samples, base_stiffness=0.0, rounds=2, fixed_base=None):
        calls.append(base_stiffness)
        if base_stiffness == 0.0:                           # the fit again: values only
            return m
        moved = m.base.vertices.copy()
        moved += 1e-4 * m.directions                         # every vertex moves a little
        moved[pulled] += 0.5 * m.directions[pulled]         # one is pulled far out...
        d = m.displacements.copy()
        star = np.unique(m.topology.face_vertex_idx[np.concatenate(
            [np.arange(m.topology.face_vertex_ptr[k], m.topology.face_vertex_ptr[k + 1])
             for k in np.flatnonzero((m.base.faces == pulled).any(axis=1))])])
        d[star] -= 0.5 * m.topology.interp[star][:, pulled].toarray().ravel()  # ...values follow
        return m.with_base_positions(moved).with_displacements(d)

    monkeypatch.setattr(fin, "fit_rounds", fake_fit)
    run = SimpleNamespace(s=preset("default"), timer=PhaseTimer(), notes={}, held_in_fit=None,
                          h=mean_edge_length(base.vertices, base.faces))
    assert fin.reach(fake_fit(run, mm, None, 1.0)).max() > 3 * fin.reach(mm).max()
    calls.clear()
    out = fin._base_moved(run, mm, None)
    assert calls == [run.s.fit_base_stiffness, 0.0]
    back = np.flatnonzero((out.base.vertices == mm.base.vertices).all(axis=1))
    ring = np.unique(base.faces[(base.faces == pulled).any(axis=1)])
    assert pulled in back and set(back) <= set(ring)       # it, and neighbours sharing its values
    np.testing.assert_allclose(out.base.vertices[far], mm.base.vertices[far] + 1e-4 * v[far])
    assert run.notes["base_fit_vertices_put_back"] == [len(back)]
    # a round that thickens nothing much is kept as it is, with no second fit
    monkeypatch.setattr(fin, "fit_rounds", lambda run, m, *a, **k: m.with_base_positions(
        m.base.vertices + 1e-4 * m.directions))
    out = fin._base_moved(run, mm, None)
    np.testing.assert_allclose(out.base.vertices, mm.base.vertices + 1e-4 * v)
    assert run.notes["base_fit_vertices_put_back"] == [len(back), 0]
    # a held vertex (its star on the reference, core.construct.held) is fixed in the round
    seen = []

    def fixed_fit(run, m, samples, base_stiffness=0.0, rounds=2, fixed_base=None):
        seen.append((base_stiffness, fixed_base))
        still = np.zeros(m.base.n_vertices, bool) if fixed_base is None else fixed_base
        step = np.where(still[:, None], 0.0, 1e-4 * m.directions)
        return m.with_base_positions(m.base.vertices + step) if base_stiffness else m

    monkeypatch.setattr(fin, "fit_rounds", fixed_fit)
    run.held_in_fit = np.zeros(base.n_vertices, bool)
    run.held_in_fit[far] = True
    out = fin._base_moved(run, mm, None)
    assert len(seen) == 1 and seen[0][1] is run.held_in_fit      # no second fit
    np.testing.assert_array_equal(out.base.vertices[far], mm.base.vertices[far])
    moved = ~run.held_in_fit
    np.testing.assert_allclose(out.base.vertices[moved], (mm.base.vertices + 1e-4 * v)[moved])
