"""Topology-keeping, error-bounded, quality-bounded edge-collapse decimation.

:func:`decimate` runs the compiled collapse loop (:mod:`core.base.collapse`) in slices of a
few thousand collapses so that it can report progress and stop when asked. Lengths (the
error bound) are in the units of the vertices; :func:`core.base.build_base` calls it in the
unit-sphere frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..runtime.jit import kernel
from ..mesh.trimesh import TriMesh
from . import heap
from .collapse import (RING, STATUS_EXHAUSTED, STATUS_GROW, STATUS_STEPS, STATUS_TARGET,
                       candidate, collapse, geometry_ok)
from .flip import flip_all
from .links import build_lists, link_ok, ring
from .quadrics import vertex_quadrics
from .topology import locked_vertices

SLICE = 4000         # collapses per compiled call between progress reports
FLIP_PASSES = 20     # the final flips stop after this many passes over the edges


class DecimateCancelled(RuntimeError):
    """``should_stop()`` returned True."""


@dataclass
class Decimation:
    """The decimated mesh and how the decimation ended.

    ``stopped``: "target" (reached ``target_faces``) or "limit" (no collapse left within the
    error bound, the topology and the shape limits). ``rejected``: how often each check
    refused a collapse: the error bound whenever an edge was evaluated (an edge over it is
    not queued), the topology and the shapes when one came off the queue. ``flips``: edges
    the final pass flipped.
    """

    vertices: np.ndarray
    faces: np.ndarray
    stopped: str
    collapses: int
    rejected: dict
    flips: int = 0


@kernel(cache=True)
def _offer(hc, hi, n, ok, err, cost, a, b, stamp, max_err, rejected):  # pragma: no cover
    """Queue the evaluated collapse of edge (a, b) if it is allowed and within the error
    bound, else count it as refused by the bound; returns the heap's new size."""
    if ok and err <= max_err:
        return heap.push(hc, hi, n, cost, a, b, stamp[a], stamp[b])
    if ok:
        rejected[0] += 1
    return n


@kernel(cache=True)
def _push_all(V, F, Q, W, isb, locked, head, nxt, falive, valive, stamp, edges, hc, hi,
              smooth, alpha, max_err, rejected):  # pragma: no cover - compiled
    q = np.empty(10)
    scratch = np.empty((6, 3))
    n = np.int64(0)   # a literal 0 would compile a second _offer for it (first-run seconds)
    for i in range(edges.shape[0]):
        a, b = edges[i, 0], edges[i, 1]
        ok, err, cost, x, y, z = candidate(a, b, V, F, Q, W, isb, locked, head, nxt, falive,
                                           smooth, alpha, q, scratch)
        n = _offer(hc, hi, n, ok, err, cost, a, b, stamp, max_err, rejected)
    return n


@kernel(cache=True)
def _run(V, F, Q, W, isb, locked, valive, falive, head, tail, nxt, stamp, mark, tag, hc, hi,
         hsize, n_faces, target, max_err, min_quality, min_dot, smooth, alpha, max_steps,
         rejected):  # pragma: no cover - compiled
    q = np.empty(10)
    scratch = np.empty((6, 3))
    buf = np.empty(RING, np.int64)
    S = np.empty(RING + 1, np.int64)
    R = np.empty(RING, np.int64)
    cap = hc.shape[0]
    steps = 0
    while True:
        if n_faces <= target:
            return hsize, n_faces, steps, STATUS_TARGET
        if steps >= max_steps:
            return hsize, n_faces, steps, STATUS_STEPS
        if hsize == 0:
            return hsize, n_faces, steps, STATUS_EXHAUSTED
        if hsize + 2 * RING > cap:
            hsize = heap.compact(hc, hi, hsize, stamp, valive)
            if hsize + 2 * RING > cap:
                return hsize, n_faces, steps, STATUS_GROW
        current = heap.is_current(hi, np.int64(0), stamp, valive)
        u, v = hi[0, 0], hi[0, 1]
        hsize = heap.pop(hc, hi, hsize)
        if not current:
            continue
        ok, err, cost, x, y, z = candidate(u, v, V, F, Q, W, isb, locked, head, nxt, falive,
                                           smooth, alpha, q, scratch)
        if not ok or err > max_err:
            rejected[0] += 1
            continue
        if locked[v] and not locked[u]:
            u, v = v, u
        if not link_ok(u, v, F, head, nxt, falive, isb, mark, tag, buf):
            rejected[1] += 1
            continue
        if not geometry_ok(u, v, x, y, z, V, F, head, nxt, falive, min_quality, min_dot, scratch):
            rejected[2] += 1
            continue
        n_faces -= collapse(u, v, x, y, z, V, F, Q, W, isb, locked, valive, falive, head, tail, nxt)
        steps += 1
        # Every edge touching the new one-ring may have changed cost or validity.
        S[0] = u
        nS = 1 + ring(u, F, head, nxt, falive, mark, tag, S[1:])
        for i in range(nS):
            stamp[S[i]] += 1
        for i in range(nS):
            w = S[i]
            nR = ring(w, F, head, nxt, falive, mark, tag, R)
            for j in range(nR):
                o = R[j]
                dup = False
                if o < w:               # an edge inside the ring is pushed from one side only
                    for t in range(nS):
                        if S[t] == o:
                            dup = True
                            break
                if dup or hsize >= cap:
                    continue
                a, b = min(w, o), max(w, o)
                ok, err, cost, x, y, z = candidate(a, b, V, F, Q, W, isb, locked, head, nxt,
                                                   falive, smooth, alpha, q, scratch)
                hsize = _offer(hc, hi, hsize, ok, err, cost, a, b, stamp, max_err, rejected)


def decimate(mesh: TriMesh, target_faces: int, max_error: float = np.inf,
             min_quality: float = 0.4, max_normal_angle_deg: float = 60.0, smooth: bool = True,
             length_weight: float = 1e-3, boundary_weight: float = 4.0, crease_weight: float = 1.0,
             feature_angle_deg: float = 50.0, flip_angle_deg: float | None = 20.0,
             progress: Callable[[int, int], None] | None = None,
             should_stop: Callable[[], bool] | None = None) -> Decimation:
    """Collapse edges of ``mesh`` until ``target_faces`` remain or no collapse is allowed.

    ``max_error``: bound on the root-mean-square distance from a merged vertex to the planes
    of the original faces it stands for (area-weighted; micromesh-tools' criterion).
    ``min_quality``: floor on 2r/R of new triangles. ``smooth``: where the planes leave the
    merged vertex free, place it at the one-rings' centre (else at the edge midpoint).
    ``length_weight``: edge length² added to the priority, relative to the error.
    ``flip_angle_deg``: afterwards, edges whose two faces are within this angle, one of them
    below ``min_quality``, are flipped where that shapes them better (:mod:`core.base.flip`;
    the diagonals within ``max_error`` of each other); None: no flips.
    ``progress(faces, target)`` is called between slices; ``should_stop()`` raises
    :class:`DecimateCancelled`.
    """
    V = mesh.vertices.copy()
    F = mesh.faces.copy()
    Q, W = vertex_quadrics(mesh, boundary_weight, crease_weight, feature_angle_deg)
    n = len(V)
    isb = np.zeros(n, bool)
    isb[mesh.edges[mesh.boundary_edges].reshape(-1)] = True
    locked = locked_vertices(mesh)
    valive = np.ones(n, bool)
    falive = np.ones(len(F), bool)
    head, tail, nxt = build_lists(F, n)
    stamp = np.zeros(n, np.int64)
    mark = np.zeros(n, np.int64)
    tag = np.zeros(1, np.int64)
    rejected = np.zeros(3, np.int64)
    max_err = float(max_error) ** 2 if np.isfinite(max_error) else np.inf
    min_dot = float(np.cos(np.radians(max_normal_angle_deg)))
    hc, hi = heap.new_heap(4 * len(mesh.edges) + 4 * RING)
    hsize = _push_all(V, F, Q, W, isb, locked, head, nxt, falive, valive, stamp, mesh.edges,
                      hc, hi, smooth, length_weight, max_err, rejected)
    n_faces, steps, total = len(F), 0, 0
    target = max(int(target_faces), 1)
    while True:
        if should_stop is not None and should_stop():
            raise DecimateCancelled("decimation cancelled")
        hsize, n_faces, steps, status = _run(
            V, F, Q, W, isb, locked, valive, falive, head, tail, nxt, stamp, mark, tag, hc, hi,
            hsize, n_faces, target, max_err, min_quality, min_dot, smooth, length_weight,
            SLICE, rejected)
        total += steps
        if progress is not None:
            progress(n_faces, target)
        if status == STATUS_GROW:
            hc = np.concatenate([hc, np.empty_like(hc)])
            hi = np.concatenate([hi, np.empty_like(hi)])
        elif status != STATUS_STEPS:
            break
    flips = 0
    if flip_angle_deg is not None:
        flat = float(np.cos(np.radians(flip_angle_deg)))
        gap = float(max_error) if np.isfinite(max_error) else 1e300
        flips = flip_all(V, F, head, tail, nxt, falive, locked, mark, tag, flat, gap,
                         min_quality, FLIP_PASSES)
    keep = F[falive]
    used, inverse = np.unique(keep, return_inverse=True)
    return Decimation(V[used], inverse.reshape(-1, 3).astype(np.int64),
                      "target" if status == STATUS_TARGET else "limit", total,
                      dict(zip(("error", "topology", "geometry"), rejected.tolist())), flips)
