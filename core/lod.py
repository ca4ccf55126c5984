"""Adaptive level of detail: per-base-face subdivision criteria, the supplement's Algorithm 1
(in-optimisation, τ = 0.1) and Algorithm 2 (post-process, τ = 0.03), ±1 balancing and a
budget of micro-triangles or bytes.

The one-ring of a base face is the faces sharing a vertex with it (``TriMesh.face_neighbors_csr``);
the ±1 rule is across shared edges (``TriMesh.face_adjacency``), which is what the micro-mesh
format's edge flags can stitch.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.spatial import cKDTree

from .microtopology import balance_levels, is_balanced  # noqa: F401  (re-exported: ±1 rule)


class LodError(ValueError):
    """Inconsistent input to the level-of-detail algorithms."""


# ----------------------------------------------------------------------------- criteria
def face_error_sums(pixel_error: np.ndarray, tri_id: np.ndarray, triangle_face: np.ndarray,
                    n_faces: int) -> np.ndarray:
    """Sum of per-pixel errors over the pixels each *base* face covers (all cameras).

    ``tri_id`` is the rasteriser's micro-triangle id per pixel (-1 on background);
    ``triangle_face`` maps micro-triangles to base faces.
    """
    err = np.asarray(pixel_error, dtype=np.float64).reshape(-1)
    tid = np.asarray(tri_id).reshape(-1)
    if err.shape != tid.shape:
        raise LodError("pixel errors and triangle ids must have the same shape")
    hit = tid >= 0
    faces = np.asarray(triangle_face)[tid[hit]]
    return np.bincount(faces, weights=err[hit], minlength=n_faces)[:n_faces]


def relative_gain(err_coarse: np.ndarray, err_fine: np.ndarray, floor: float | None = None) -> np.ndarray:
    """SubdivisionCriterion: relative error improvement (E_coarse - E_fine) / E_coarse per face.

    ``floor`` (default: 1e-3 of the mean non-zero coarse error) keeps faces that are already
    nearly exact, or barely visible, from producing large noisy ratios: they get gain ≈ 0.
    """
    c = np.asarray(err_coarse, dtype=np.float64)
    f = np.asarray(err_fine, dtype=np.float64)
    if floor is None:
        nz = c[c > 0]
        floor = 1e-3 * float(nz.mean()) if nz.size else 1e-12
    return (c - f) / np.maximum(c, floor)


def chamfer_face_errors(micro_vertices: np.ndarray, micro_vertex_face: np.ndarray,
                        reference_points: np.ndarray, n_faces: int,
                        ref_tree: cKDTree | None = None) -> np.ndarray:
    """Per base face, a two-sided Chamfer distance between its patch and the reference.

    Side 1: mean distance of the face's micro-vertices to the nearest reference point.
    Side 2: mean distance of the reference points whose nearest micro-vertex is on the face.
    (Point-to-point against the dense reference vertices: the ablation criterion, Tab. 1a.)
    """
    mv = np.asarray(micro_vertices, dtype=np.float64)
    mf = np.asarray(micro_vertex_face, dtype=np.int64)
    rp = np.asarray(reference_points, dtype=np.float64)
    tree = ref_tree if ref_tree is not None else cKDTree(rp)
    d1, _ = tree.query(mv)
    s1 = np.bincount(mf, weights=d1, minlength=n_faces)[:n_faces]
    c1 = np.bincount(mf, minlength=n_faces)[:n_faces]
    d2, j = cKDTree(mv).query(rp)
    f2 = mf[j]
    s2 = np.bincount(f2, weights=d2, minlength=n_faces)[:n_faces]
    c2 = np.bincount(f2, minlength=n_faces)[:n_faces]
    return s1 / np.maximum(c1, 1) + s2 / np.maximum(c2, 1)


# ----------------------------------------------------------------------------- helpers
def _ring_min_max(levels: np.ndarray, ring: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per face, min and max level over its one-ring (its own level where the ring is empty)."""
    ptr, idx = ring
    lo = levels.copy()
    hi = levels.copy()
    counts = np.diff(ptr)
    has = counts > 0
    if idx.size:
        vals = levels[idx]
        starts = ptr[:-1][has]
        lo[has] = np.minimum.reduceat(vals, starts)
        hi[has] = np.maximum.reduceat(vals, starts)
    return lo, hi


def micro_triangle_count(levels: np.ndarray) -> int:
    """Micro-triangles of the full subdivisions (before the crack-free edge decimation)."""
    return int(np.sum(4 ** np.asarray(levels, dtype=np.int64)))


def effective_micro_triangles(levels: np.ndarray, face_adjacency: np.ndarray) -> int:
    """Micro-triangles the tessellation really has: a face at level l loses 2**(l-1) of them
    along each edge whose neighbour is one level coarser (the edge decimation that keeps the
    surface crack-free). ``face_adjacency``: (F, 3) neighbour across each edge, -1 none."""
    lv = np.asarray(levels, dtype=np.int64)
    adj = np.asarray(face_adjacency)
    nb = np.where(adj >= 0, lv[np.maximum(adj, 0)], lv[:, None])
    coarser = (nb == lv[:, None] - 1).sum(axis=1)
    return int(np.sum(4 ** lv) - np.sum(coarser * (1 << np.maximum(lv - 1, 0))))


# ------------------------------------------------------------------------ algorithms
def in_optimization_lod(levels: np.ndarray, level: int, min_level: int, gains: np.ndarray | None,
                        one_ring: tuple[np.ndarray, np.ndarray], tau: float = 0.1) -> np.ndarray:
    """Algorithm 1: levels after the subdivision from ``level`` to ``level + 1``.

    Below ``min_level`` every face goes on. From ``min_level``, a face at ``level`` goes on
    only if no face in its one-ring stopped earlier (all are ≥ ``level``) and its gain (the
    improvement level ``level`` brought over ``level - 1``) exceeds ``tau``. Level 0 has no
    gain to judge (there is no level −1), so with ``min_level`` 0 every face still goes on
    to level 1; Algorithm 2 may roll faces back to 0.
    """
    lv = np.asarray(levels, dtype=np.int64).copy()
    if level < max(min_level, 1):
        lv[:] = level + 1
        return lv
    if gains is None or len(gains) != len(lv):
        raise LodError("Algorithm 1 needs one gain per base face from min_level on")
    ring_lo, _ = _ring_min_max(lv, one_ring)
    go = (lv == level) & (ring_lo >= level) & (np.asarray(gains) > tau)
    lv[go] = level + 1
    return lv


def post_process_lod(gains_by_level: dict[int, np.ndarray], max_level: int, min_level: int,
                     one_ring: tuple[np.ndarray, np.ndarray], tau: float = 0.03,
                     n_faces: int | None = None) -> np.ndarray:
    """Algorithm 2: roll faces back from a uniform ``max_level`` run.

    ``gains_by_level[l]`` is the improvement level ``l`` brings over ``l - 1`` per face. At
    ``max_level`` any face below ``tau`` rolls back; then, level by level down to
    ``min_level + 1``, a face at that level rolls back if its gain is below ``tau`` and no
    face in its one-ring stopped rolling back (all are ≤ that level).
    """
    if n_faces is None:
        n_faces = len(next(iter(gains_by_level.values())))
    lv = np.full(n_faces, max_level, dtype=np.int64)
    if max_level <= min_level:
        return lv
    lv[np.asarray(gains_by_level[max_level]) < tau] = max_level - 1
    level = max_level - 1
    while level > min_level:
        _, ring_hi = _ring_min_max(lv, one_ring)
        back = (lv == level) & (ring_hi <= level) & (np.asarray(gains_by_level[level]) < tau)
        lv[back] = level - 1
        level -= 1
    return lv


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
                       face_adjacency: np.ndarray, cost: Callable[[np.ndarray], float],
                       budget: float, min_level: int = 0) -> np.ndarray:
    """Spend a binding budget where it helps most (ours): subdivide faces at ``level`` to
    ``level + 1`` paid for by rolling other faces at ``level`` back to ``level - 1``.

    Expected value of going up: ``err_now · gain`` (the last level's relative improvement,
    assumed to repeat); value lost going down: ``err_prev - err_now`` (what the last level
    bought). A subdivision is taken while its value exceeds that of the roll-backs paying for
    it; the ±1 rule is restored by raising, and what then overflows the budget is cut.
    """
    lv = np.asarray(levels, dtype=np.int64).copy()
    adj = np.asarray(face_adjacency)
    ok = adj >= 0
    at = lv == level
    e0, e1 = np.asarray(err_prev, float), np.asarray(err_now, float)
    gain = relative_gain(e0, e1)
    up_val = e1 * np.clip(gain, 0, None)
    down_val = np.clip(e0 - e1, 0, None)
    nb_lo = np.where(ok, lv[np.maximum(adj, 0)], 99).min(axis=1)
    nb_hi = np.where(ok, lv[np.maximum(adj, 0)], -1).max(axis=1)
    ups = np.flatnonzero(at & (nb_lo >= level) & (up_val > 0))
    ups = ups[np.argsort(-up_val[ups], kind="stable")]
    downs = np.flatnonzero(at & (nb_hi <= level)) if level - 1 >= min_level else np.array([], int)
    downs = downs[np.argsort(down_val[downs], kind="stable")]
    c_up = 3 * 4 ** level
    c_down = 3 * 4 ** (level - 1)
    slack = budget - cost(lv)
    taken_up, taken_down = [], []
    # state: 0 free, 1 going up, -1 going down; an up may not touch a down across an edge.
    state = np.zeros(len(lv), np.int64)

    def touches(f, kind):
        a = adj[f]
        a = a[a >= 0]
        return bool((state[a] == kind).any())

    j = 0
    for f in ups:
        if state[f] != 0 or touches(f, -1):
            continue
        if slack >= c_up:
            taken_up.append(f)
            state[f] = 1
            slack -= c_up
            continue
        need = int(np.ceil((c_up - slack) / c_down))
        cand = []
        k = j
        while len(cand) < need and k < len(downs):
            g = downs[k]
            k += 1
            if g == f or state[g] != 0 or touches(g, 1) or g in adj[f]:
                continue
            cand.append(g)
        if len(cand) < need or down_val[cand].sum() >= up_val[f]:
            break
        taken_up.append(f)
        state[f] = 1
        taken_down += cand
        state[cand] = -1
        slack += need * c_down - c_up
        j = k
    new = lv.copy()
    new[taken_down] = level - 1
    new[taken_up] = level + 1
    new = balance_levels_adjacency(adj, new)
    if cost(new) > budget:           # balancing raised some roll-backs: cut the weakest ups
        order = np.array(taken_up)[::-1]
        lo, hi = 0, len(order)
        while lo < hi:
            mid = (lo + hi) // 2
            trial = new.copy()
            trial[order[:mid]] = level
            trial = balance_levels_adjacency(adj, trial)
            if cost(trial) <= budget:
                hi = mid
            else:
                lo = mid + 1
        new[order[:lo]] = level
        new = balance_levels_adjacency(adj, new)
        if cost(new) > budget:
            return lv
    return new


def balance_levels_adjacency(face_adjacency: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Raise the lower side until faces across manifold edges differ by at most one level."""
    adj = np.asarray(face_adjacency)
    lv = np.asarray(levels, dtype=np.int64).copy()
    ok = adj >= 0
    while True:
        nb = np.where(ok, lv[np.maximum(adj, 0)], -10).max(axis=1)
        new = np.maximum(lv, nb - 1)
        if np.array_equal(new, lv):
            return lv
        lv = new


def roll_back_to_budget(levels: np.ndarray, gains_by_level: dict[int, np.ndarray],
                        face_adjacency: np.ndarray, cost: Callable[[np.ndarray], float],
                        budget: float, min_level: int = 0) -> np.ndarray:
    """Lower the least useful faces (smallest gain of their level) until ``cost ≤ budget``,
    only where the ±1 rule allows (no edge neighbour above the face's level)."""
    lv = np.asarray(levels, dtype=np.int64).copy()
    adj = np.asarray(face_adjacency)
    ok = adj >= 0
    while budget > 0 and cost(lv) > budget:
        top = lv.max()
        if top <= min_level:
            break
        nb_hi = np.where(ok, lv[np.maximum(adj, 0)], -10).max(axis=1)
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
