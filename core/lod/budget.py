"""Levels within a budget (micro-triangles or bytes; ours): cut the weakest subdivisions,
exchange ups for roll-backs where the image error says so, roll back the least useful faces.
The ±1 rule is ``core.micro.levels``': across every edge, among all the faces on it."""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..mesh.trimesh import TriMesh
from ..micro.levels import balance_levels, face_edge_levels
from .criteria import relative_gain


def trim_to_budget(old_levels: np.ndarray, new_levels: np.ndarray, gains: np.ndarray,
                   cost: Callable[[np.ndarray], float], budget: float) -> np.ndarray:
    """Keep only the highest-gain subdivisions of ``old → new`` so that ``cost(levels) ≤ budget``.

    Dropping a subdivision chosen by Algorithm 1 never breaks the ±1 rule (its neighbours were
    all at least at the old level), so this is a greedy cut along the gain order.
    """
    old = np.asarray(old_levels, dtype=np.int64)
    new = np.asarray(new_levels, dtype=np.int64).copy()
    if budget <= 0 or cost(new) <= budget:
        return new
    cand = np.flatnonzero(new > old)
    order = cand[np.argsort(-np.asarray(gains)[cand], kind="stable")]
    lo, hi = 0, len(order)                      # binary search on how many to keep
    while lo < hi:
        mid = (lo + hi + 1) // 2
        trial = old.copy()
        trial[order[:mid]] = new[order[:mid]]
        if cost(trial) <= budget:
            lo = mid
        else:
            hi = mid - 1
    out = old.copy()
    out[order[:lo]] = new[order[:lo]]
    return out


def exchange_to_budget(levels: np.ndarray, level: int, err_prev: np.ndarray, err_now: np.ndarray,
                       mesh: TriMesh, cost: Callable[[np.ndarray], float],
                       budget: float, min_level: int = 0) -> np.ndarray:
    """Spend a binding budget where it helps most (ours): subdivide faces at ``level`` to
    ``level + 1`` paid for by rolling other faces at ``level`` back to ``level - 1``.

    Expected value of going up: ``err_now · gain`` (the last level's relative improvement,
    assumed to repeat); value lost going down: ``err_prev - err_now`` (what the last level
    bought). A subdivision is taken while its value exceeds that of the roll-backs paying for
    it; the ±1 rule is restored by raising, and what then overflows the budget is cut.
    """
    lv = np.asarray(levels, dtype=np.int64).copy()
    e0, e1 = np.asarray(err_prev, float), np.asarray(err_now, float)
    up_val = e1 * np.clip(relative_gain(e0, e1), 0, None)
    down_val = np.clip(e0 - e1, 0, None)
    ups, downs = _candidates(lv, level, mesh, up_val, down_val, min_level)
    trade = _Trade(mesh.edge_neighbors_csr, budget - cost(lv), *_step_costs(lv, level, cost))
    trade.pair(ups, downs, up_val, down_val)
    new = lv.copy()
    new[trade.downs] = level - 1
    new[trade.ups] = level + 1
    new = balance_levels(mesh, new)
    if cost(new) > budget:           # balancing raised some roll-backs: cut the weakest ups
        new = _cut_ups(new, trade.ups, level, mesh, cost, budget)
        if cost(new) > budget:
            return lv
    return new


def _step_costs(lv: np.ndarray, level: int, cost) -> tuple[float, float]:
    """What one face at ``level`` costs going up a level, and saves going down, in the
    budget's unit (micro-triangles or bytes): measured on a face at that level."""
    at = np.flatnonzero(lv == level)
    if len(at) == 0:
        return 3.0 * 4 ** level, 3.0 * 4 ** (level - 1)
    now, trial = cost(lv), lv.copy()
    trial[at[0]] = level + 1
    up = cost(trial) - now
    trial[at[0]] = level - 1
    down = now - cost(trial)
    return max(float(up), 1e-9), max(float(down), 1e-9)


def _candidates(lv, level, mesh, up_val, down_val, min_level):
    """Faces at ``level`` that may go up (no edge neighbour below it; best first) and that may
    go down (no edge neighbour above it; least useful first)."""
    at = lv == level
    lo, hi = face_edge_levels(mesh, lv)
    nb_lo, nb_hi = lo.min(axis=1), hi.max(axis=1)
    ups = np.flatnonzero(at & (nb_lo >= level) & (up_val > 0))
    ups = ups[np.argsort(-up_val[ups], kind="stable")]
    downs = np.flatnonzero(at & (nb_hi <= level)) if level - 1 >= min_level else np.array([], int)
    return ups, downs[np.argsort(down_val[downs], kind="stable")]


class _Trade:
    """The greedy pairing of ups with the roll-backs that pay for them: ``state`` per face
    (0 free, 1 going up, -1 going down; an up may not touch a down across an edge: ``ring``,
    ``TriMesh.edge_neighbors_csr``), the budget's ``slack`` and the faces taken."""

    def __init__(self, ring, slack, c_up, c_down):
        self.ring, self.slack, self.c_up, self.c_down = ring, slack, c_up, c_down
        self.state = np.zeros(len(ring[0]) - 1, np.int64)
        self.ups: list[int] = []
        self.downs: list[int] = []

    def across(self, f) -> np.ndarray:
        ptr, idx = self.ring
        return idx[ptr[f]:ptr[f + 1]]

    def touches(self, f, kind) -> bool:
        return bool((self.state[self.across(f)] == kind).any())

    def pair(self, ups, downs, up_val, down_val) -> None:
        j = 0
        for f in ups:
            if self.state[f] != 0 or self.touches(f, -1):
                continue
            if self.slack >= self.c_up:
                self._take([f], [])
                continue
            need = int(np.ceil((self.c_up - self.slack) / self.c_down))
            cand, k, near = [], j, self.across(f)
            while len(cand) < need and k < len(downs):
                g = downs[k]
                k += 1
                if g == f or self.state[g] != 0 or self.touches(g, 1) or g in near:
                    continue
                cand.append(g)
            if len(cand) < need or down_val[cand].sum() >= up_val[f]:
                break
            self._take([f], cand)
            j = k

    def _take(self, ups, downs) -> None:
        self.ups += ups
        self.downs += downs
        self.state[ups] = 1
        self.state[downs] = -1
        self.slack += len(downs) * self.c_down - len(ups) * self.c_up


def _cut_ups(new, taken_up, level, mesh, cost, budget):
    """``new`` with the fewest of the last-taken ups set back to ``level`` (binary search)
    so that, balanced, it fits the budget."""
    order = np.array(taken_up, dtype=np.int64)[::-1]
    lo, hi = 0, len(order)
    while lo < hi:
        mid = (lo + hi) // 2
        trial = new.copy()
        trial[order[:mid]] = level
        trial = balance_levels(mesh, trial)
        if cost(trial) <= budget:
            hi = mid
        else:
            lo = mid + 1
    new = new.copy()
    new[order[:lo]] = level
    return balance_levels(mesh, new)


def roll_back_to_budget(levels: np.ndarray, gains_by_level: dict[int, np.ndarray],
                        mesh: TriMesh, cost: Callable[[np.ndarray], float],
                        budget: float, min_level: int = 0) -> np.ndarray:
    """Lower the least useful faces (smallest gain of their level) until ``cost ≤ budget``,
    only where the ±1 rule allows (no edge neighbour above the face's level)."""
    lv = np.asarray(levels, dtype=np.int64).copy()
    while budget > 0 and cost(lv) > budget:
        top = lv.max()
        if top <= min_level:
            break
        nb_hi = face_edge_levels(mesh, lv)[1].max(axis=1)
        cand = np.flatnonzero((lv == top) & (nb_hi <= top))
        if cand.size == 0:
            break
        g = np.asarray(gains_by_level.get(int(top), np.zeros(len(lv))))[cand]
        order = cand[np.argsort(g, kind="stable")]
        # Each rollback at level `top` saves 3 * 4^(top-1) triangles; take enough in one go,
        # but never more than the candidates, then re-check (neighbour constraints change).
        excess = cost(lv) - budget
        per = cost(np.where(np.arange(len(lv)) == order[0], lv - 1, lv))
        saving = max(cost(lv) - per, 1e-9)
        k = int(min(len(order), max(1, np.ceil(excess / saving))))
        # A face and its edge neighbour may both roll back together only if that keeps ±1:
        # they are at the same level, so after both go down it still holds.
        lv[order[:k]] -= 1
    return lv
