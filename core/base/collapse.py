"""Edge-collapse decimation that keeps topology, bounds the error and keeps triangles well
shaped (numba kernels; :func:`core.base.decimate.decimate` drives them).

One collapse merges v into u at the minimiser of the summed quadrics; where the planes leave
it free (flat regions, along a crease) at the centre of the one-rings instead (like
micromesh-tools' "vertex smoothing", it evens the triangles out). It is taken when
- the error (area-weighted mean squared distance to the merged planes) is within the bound;
- the link condition holds (:func:`core.base.links.link_ok`): genus, components and
  boundary loops stay as they are and the surface stays a manifold;
- no remaining face turns by more than ``acos(min_normal_dot)`` (no fold-overs);
- the worst new triangle's quality 2r/R is at least ``min(min_quality, the worst old one
  around)``, so slivers are never made and existing ones can only improve.
Candidates pop from a lazy-deletion heap (:mod:`core.base.heap`) ordered by error plus a
small multiple of the edge length², which decimates flat regions evenly.
"""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel
from .links import compact_list
from .placement import place, quadric_error_at, triangle_quality

RING = 4096          # neighbour buffer size (valences above it are truncated in pushes)
STATUS_TARGET, STATUS_EXHAUSTED, STATUS_STEPS, STATUS_GROW = 0, 1, 2, 3


@kernel(cache=True)
def candidate(u, v, V, F, Q, W, isb, locked, head, nxt, falive, smooth, alpha, q,
              scratch):  # pragma: no cover - compiled
    """(ok, error, cost, x, y, z) of collapsing edge (u, v); ``q`` (10,) and ``scratch`` (6, 3)
    are scratch arrays. ``smooth``: place towards the one-rings' centre, else the midpoint."""
    w = W[u] + W[v]
    if w <= 0:
        w = 1e-300
    for i in range(10):
        q[i] = (Q[u, i] + Q[v, i]) / w
    ex, ey, ez = V[v, 0] - V[u, 0], V[v, 1] - V[u, 1], V[v, 2] - V[u, 2]
    len2 = ex * ex + ey * ey + ez * ez
    mx, my, mz = 0.5 * (V[u, 0] + V[v, 0]), 0.5 * (V[u, 1] + V[v, 1]), 0.5 * (V[u, 2] + V[v, 2])
    if locked[u] and locked[v]:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0
    if locked[u] or locked[v]:
        s = u if locked[u] else v
        x, y, z = V[s, 0], V[s, 1], V[s, 2]
    else:
        lx, ly, lz = mx, my, mz
        if smooth and not (isb[u] or isb[v]):
            # Centre of the two one-rings, projected on the tangent plane at the midpoint.
            cx = cy = cz = 0.0
            nx = ny = nz = 0.0
            cnt = 0.0
            for a in (u, v):
                k = head[a]
                while k >= 0:
                    f = k // 3
                    if falive[f]:
                        for c in range(3):
                            b = F[f, c]
                            cx += V[b, 0]
                            cy += V[b, 1]
                            cz += V[b, 2]
                            cnt += 1.0
                        p0, p1, p2 = F[f, 0], F[f, 1], F[f, 2]
                        _, fx, fy, fz = triangle_quality(V[p0, 0], V[p0, 1], V[p0, 2], V[p1, 0],
                                                 V[p1, 1], V[p1, 2], V[p2, 0], V[p2, 1], V[p2, 2])
                        nx += fx
                        ny += fy
                        nz += fz
                    k = nxt[k]
            nn = np.sqrt(nx * nx + ny * ny + nz * nz)
            if cnt > 0 and nn > 0:
                cx, cy, cz = cx / cnt, cy / cnt, cz / cnt
                nx, ny, nz = nx / nn, ny / nn, nz / nn
                t = (cx - mx) * nx + (cy - my) * ny + (cz - mz) * nz
                lx, ly, lz = cx - t * nx, cy - t * ny, cz - t * nz
        x, y, z = place(q, lx, ly, lz, scratch)
        if (x - mx) ** 2 + (y - my) ** 2 + (z - mz) ** 2 > 4.0 * len2:
            # Ill-conditioned far away: the best of the two ends and the midpoint.
            x, y, z = mx, my, mz
            best = quadric_error_at(q, mx, my, mz)
            for a in (u, v):
                e = quadric_error_at(q, V[a, 0], V[a, 1], V[a, 2])
                if e < best:
                    best = e
                    x, y, z = V[a, 0], V[a, 1], V[a, 2]
    err = max(quadric_error_at(q, x, y, z), 0.0)
    return True, err, err + alpha * len2, x, y, z


@kernel(cache=True)
def geometry_ok(u, v, x, y, z, V, F, head, nxt, falive, min_quality, min_dot, p):  # pragma: no cover
    """No face around the edge flips or turns past ``min_dot``, none degenerates, and the
    worst new quality is at least min(min_quality, the worst old quality around).
    ``p`` is a (3, 3) or larger scratch array (its first three rows are used)."""
    q_old = 1.0
    q_new = 1.0
    for a in (u, v):
        k = head[a]
        while k >= 0:
            f = k // 3
            if falive[f]:
                i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
                qo, ox, oy, oz = triangle_quality(V[i0, 0], V[i0, 1], V[i0, 2], V[i1, 0], V[i1, 1],
                                          V[i1, 2], V[i2, 0], V[i2, 1], V[i2, 2])
                both = (i0 == u or i1 == u or i2 == u) and (i0 == v or i1 == v or i2 == v)
                if a == u or not both:
                    q_old = min(q_old, qo)
                if not both:
                    c = k % 3
                    for j in range(3):
                        vj = F[f, j]
                        p[j, 0], p[j, 1], p[j, 2] = V[vj, 0], V[vj, 1], V[vj, 2]
                    p[c, 0], p[c, 1], p[c, 2] = x, y, z
                    qn, nx, ny, nz = triangle_quality(p[0, 0], p[0, 1], p[0, 2], p[1, 0], p[1, 1],
                                              p[1, 2], p[2, 0], p[2, 1], p[2, 2])
                    ln = np.sqrt(nx * nx + ny * ny + nz * nz)
                    lo = np.sqrt(ox * ox + oy * oy + oz * oz)
                    if ln <= 1e-300 or qn <= 0:
                        return False
                    if ox * nx + oy * ny + oz * nz < min_dot * lo * ln:
                        return False
                    q_new = min(q_new, qn)
            k = nxt[k]
    return q_new >= min(min_quality, q_old)


@kernel(cache=True)
def collapse(u, v, x, y, z, V, F, Q, W, isb, locked, valive, falive, head, tail, nxt):  # pragma: no cover
    """Merge v into u at (x, y, z); returns the number of faces removed."""
    removed = 0
    k = head[v]
    while k >= 0:
        f = k // 3
        if falive[f]:
            if F[f, 0] == u or F[f, 1] == u or F[f, 2] == u:
                falive[f] = False
                removed += 1
                for c in range(3):
                    o = F[f, c]
                    if o != u and o != v:
                        compact_list(o, head, tail, nxt, falive)
            else:
                F[f, k % 3] = u
        k = nxt[k]
    if head[v] >= 0:
        if head[u] < 0:
            head[u] = head[v]
        else:
            nxt[tail[u]] = head[v]
        tail[u] = tail[v]
    head[v] = -1
    tail[v] = -1
    valive[v] = False
    compact_list(u, head, tail, nxt, falive)
    V[u, 0], V[u, 1], V[u, 2] = x, y, z
    for i in range(10):
        Q[u, i] += Q[v, i]
    W[u] += W[v]
    isb[u] = isb[u] or isb[v]
    locked[u] = locked[u] or locked[v]
    return removed
