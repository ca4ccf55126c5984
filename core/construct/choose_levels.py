"""Which faces get which level (method §5): Algorithm 1 at each subdivision event
(:func:`subdivide`: the per-face errors measured, the next levels chosen, the new
micro-vertices given their displacements, those that existed keeping their optimised
values), Algorithm 2 after the run, and the storage budget spent by visual gain in both."""
from __future__ import annotations

import numpy as np

from ..lod import (effective_micro_triangles, exchange_to_budget, in_optimization_lod,
                   post_process_lod, relative_gain, roll_back_to_budget, trim_to_budget)
from ..micro.levels import balance_levels, face_edge_levels
from ..micro.micromesh import MicroMesh
from ..spatial.bake import SOURCE_NEAREST, bake_displacements
from .params import Parameters
from .scene import face_errors
from .state import RunState


def next_levels(run: RunState, old: np.ndarray, errs: np.ndarray | None,
                gains: np.ndarray | None) -> np.ndarray:
    """Levels after the subdivision from ``run.level`` (balanced, within ℓmax and the budget).

    ``errs``: per-face errors now; ``gains``: what ``run.level`` brought over the level before
    (None before ℓmin or without the visual criterion)."""
    s, base, level = run.s, run.base, run.level
    if s.lod == "in_optim":
        # With a budget, the budget decides (ours): Algorithm 1 runs with τ = -inf (the
        # one-ring rule still holds) and a binding budget is then spent by gain order.
        tau = -np.inf if run.cost is not None else s.tau_in
        new = in_optimization_lod(old, level, s.min_level, gains, base.face_neighbors_csr, tau)
    else:
        new = np.where(old == level, level + 1, old)
    if run.cost is not None and run.cost(new) > run.budget:
        if s.lod == "in_optim" and gains is not None and level >= 1:
            new = exchange_to_budget(old, level, run.last_errors, errs, base, run.cost,
                                     run.budget, s.min_level)
        else:
            prio = gains if gains is not None else errs
            new = trim_to_budget(old, new, prio, run.cost, run.budget)
    return balance_levels(base, np.minimum(new, s.max_level))


def final_levels(run: RunState, mm: MicroMesh) -> MicroMesh:
    """After the optimisation: Algorithm 2 (``lod="post"``) or a roll-back into the budget,
    then what the budget still allows is spent (:func:`fill_budget`); the artist's fixed
    levels are kept as they are."""
    s = run.s
    if run.fixed is not None:
        return mm
    if s.lod == "post" and mm.levels.max() > s.min_level:
        with run.timer.phase("post_lod"):
            mm = _post_process(run, mm)
    elif run.cost is not None and run.cost(mm.levels) > run.budget:
        with run.timer.phase("post_lod"):
            mm = mm.with_levels(roll_back_to_budget(mm.levels, run.gains, run.base, run.cost,
                                                    run.budget, s.min_level))
    if run.cost is not None and run.cost(mm.levels) < run.budget:
        new = fill_budget(run, mm.levels)
        if not np.array_equal(new, mm.levels):
            mm = mm.with_levels(new)
    return mm


def fill_budget(run: RunState, levels: np.ndarray) -> np.ndarray:
    """Raise faces one level, highest gain first, while the budget allows (ours): the
    balancing and the granularity of the events leave up to a tenth of it unspent. Only
    faces with no edge neighbour below them (all the faces of a non-manifold edge) go up, so
    the ±1 rule holds; a face's gain is what its current level brought over the one before."""
    lv = np.asarray(levels, dtype=np.int64)
    up = (lv < run.s.max_level) & (face_edge_levels(run.base, lv)[0].min(axis=1) >= lv)
    gain = np.zeros(len(lv))
    for level, g in run.gains.items():
        gain = np.where(lv == level, np.asarray(g, float), gain)
    return trim_to_budget(lv, np.where(up, lv + 1, lv), np.where(up, gain, -np.inf), run.cost,
                          run.budget)


def _post_process(run: RunState, mm: MicroMesh) -> MicroMesh:
    """Algorithm 2 on the optimised mesh: per-face errors at every level from ℓmin to the top
    (the finished surface resampled at uniform levels), roll back, then fit the budget."""
    s = run.s
    top = int(mm.levels.max())
    nf = mm.base.n_faces
    errs = {}
    for lv in range(max(0, s.min_level - 1), top + 1):
        run.check_stop()
        m = mm if (mm.levels == lv).all() else mm.with_levels(np.full(nf, lv))
        errs[lv] = face_errors(m, run.scene, run.lod_cams, s, run.ref_tree)
    gains = {lv: relative_gain(errs[lv - 1], errs[lv]) for lv in errs if lv - 1 in errs}
    run.gains.update(gains)
    new = post_process_lod(gains, top, s.min_level, mm.base.face_neighbors_csr, s.tau_post)
    new = np.minimum(new, mm.levels)
    new = balance_levels(mm.base, new)
    if run.cost is not None and run.cost(new) > run.budget:
        new = roll_back_to_budget(new, gains, mm.base, run.cost, run.budget, s.min_level)
    return mm.with_levels(new)



def residual_exchange(run: RunState, levels: np.ndarray, residuals: np.ndarray) -> np.ndarray:
    """Levels moved to where the fitted micro-mesh still misses the reference (ours), at the
    same budget: the ``s.residual_lod`` fraction of faces with the largest residual per
    micro-triangle a level up would add go up (balanced); then faces with the smallest
    residual per micro-triangle saved go down (only where no edge neighbour, of all the faces
    on a non-manifold edge, is above them, which keeps the ±1 rule) until the budget holds
    (where they cannot pay for all the ups, half as many ups are tried, down to an eighth);
    what is left is spent by the same order as the ups. A level up is taken to remove 3/4
    of a face's residual, a level down to quadruple it."""
    s = run.s
    lv = np.asarray(levels, dtype=np.int64)
    if run.cost is None or s.residual_lod <= 0:
        return lv
    E = np.asarray(residuals, dtype=np.float64)
    up_gain = np.where(lv < s.max_level, E / 4.0 ** lv, -np.inf)
    ranked = np.argsort(-up_gain, kind="stable")
    n_up = int(s.residual_lod * np.isfinite(up_gain).sum())
    for k in (n_up, n_up // 2, n_up // 4, n_up // 8):
        new = _exchanged(run, lv, ranked[:k], E) if k > 0 else None
        if new is not None:
            return new
    return lv


def _exchanged(run: RunState, lv: np.ndarray, ups: np.ndarray, E: np.ndarray
               ) -> np.ndarray | None:
    """:func:`residual_exchange` with these ups; None where the downs cannot pay for them."""
    s, base = run.s, run.base
    new = lv.copy()
    new[ups] += 1
    new = balance_levels(base, np.minimum(new, s.max_level))
    if run.cost(new) > run.budget:
        nb_hi = face_edge_levels(base, new)[1].max(axis=1)
        cand = np.flatnonzero((new > max(s.min_level, 0)) & (nb_hi <= new) & (new <= lv))
        order = cand[np.argsort(E[cand] / 4.0 ** (new[cand] - 1), kind="stable")]
        lo, hi = 0, len(order)              # the fewest downs that fit the budget
        while lo < hi:
            mid = (lo + hi) // 2
            trial = new.copy()
            trial[order[:mid]] -= 1
            if run.cost(trial) <= run.budget:
                hi = mid
            else:
                lo = mid + 1
        new[order[:lo]] -= 1
        if run.cost(new) > run.budget:
            return None
    up = (new < s.max_level) & (face_edge_levels(base, new)[0].min(axis=1) >= new)
    return trim_to_budget(new, np.where(up, new + 1, new),
                          np.where(up, E / 4.0 ** new, -np.inf), run.cost, run.budget)


def subdivide(run: RunState, params: Parameters, it: int) -> None:
    """One level up where the LOD and the budget allow; ``run.level`` advances either way."""
    s = run.s
    cur = params.micromesh()
    old = cur.levels.copy()
    errs = face_errors(cur, run.scene, run.lod_cams, s, run.ref_tree) \
        if (s.lod == "in_optim" or run.budget > 0) else None
    gains = None
    if errs is not None and run.last_errors is not None:
        gains = relative_gain(run.last_errors, errs)
        run.gains[run.level] = gains
    new = next_levels(run, old, errs, gains)
    if errs is not None:
        run.last_errors = errs
    if np.array_equal(new, old):
        run.event(iteration=it, level=run.level + 1, subdivided=0)
        run.level += 1
        return
    nxt, kept = cur.resampled(new)
    if not kept.all():
        # New micro-vertices: projected onto the reference ("bake", ours), or onto the
        # current displaced surface ("interpolate", the paper's rule made exact: each lies on
        # the surface it subdivides); "rebake" projects every micro-vertex onto the
        # reference again (the measurement's alternative). The warm-up left the level-0
        # values at zero, untrained: those are baked too. Where a projection falls back to
        # the nearest point (no ray hit within reach: the spikes of plain baking) the
        # resampled value stays.
        warmed = s.base_warm_up and run.level == 0
        every = s.init_new_levels == "rebake" or (warmed and s.init_new_levels == "bake")
        todo = np.arange(nxt.n_vertices) if every else np.flatnonzero(~kept)
        onto = cur.tessellate().to_trimesh() if s.init_new_levels == "interpolate" and \
            not warmed else run.scene.ref
        br = bake_displacements(nxt.micro_vertex_base_positions()[todo],
                                nxt.micro_vertex_directions()[todo], onto,
                                max_distance=run.bake_distance)
        d = nxt.displacements.copy()
        d[todo] = np.where(br.source == SOURCE_NEAREST, d[todo], br.displacement)
        nxt = nxt.with_displacements(d)
    params.set_micromesh(nxt)
    run.event(iteration=it, level=run.level + 1, subdivided=int((new > old).sum()),
              micro_triangles=effective_micro_triangles(new, run.base))
    run.level += 1
