"""Edge flips after the decimation (numba kernels; :func:`core.base.decimate.decimate` calls
:func:`flip_all` once the collapses are done).

The collapses leave each quad split along whichever diagonal they made, and where the input's
triangles were slivers (flat regions of CAD parts, long strips) the quality floor could only
keep them from getting worse. Where a quad has a triangle below the floor and its two
triangles would be better shaped split along the other diagonal, the edge is flipped: better
shapes at the same vertices and face count (micromesh-tools flips edges in its decimation
too). Quads whose triangles are all above the floor are left as the collapses made them: on
organic meshes flipping those too cost up to 0.23 dB in the end (``docs/results.md``).

An edge (u, o) with faces (u, o, a) and (o, u, b) becomes (a, b) when
- one of the two faces is below ``below`` (2r/R);
- both faces are alive, consistently oriented, and nothing of the quad is locked;
- the edge (a, b) does not exist yet and u and o keep at least three neighbours;
- the quad is nearly flat (its faces' normals within ``min_cos``), the two diagonals pass
  within ``max_gap`` of each other (the surface moves by no more), and the new faces stay
  within the same angle of the quad's mean normal;
- the worse of the two triangles' quality 2r/R rises by at least ``GAIN``, so flips never
  undo each other and the passes end.
"""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel
from .collapse import RING
from .placement import triangle_quality
from .links import ring

GAIN = 1e-3        # the smallest rise of the worse quality that a flip must bring


@kernel(cache=True)
def _move(k, src, dst, head, tail, nxt):  # pragma: no cover - compiled
    """Move node k from the list of ``src`` to the end of the list of ``dst``."""
    prev = -1
    j = head[src]
    while j >= 0 and j != k:
        prev = j
        j = nxt[j]
    if j < 0:
        return
    if prev < 0:
        head[src] = nxt[k]
    else:
        nxt[prev] = nxt[k]
    if tail[src] == k:
        tail[src] = prev
    nxt[k] = -1
    if head[dst] < 0:
        head[dst] = k
    else:
        nxt[tail[dst]] = k
    tail[dst] = k


@kernel(cache=True)
def _adjacent(a, b, F, head, nxt, falive):  # pragma: no cover - compiled
    k = head[a]
    while k >= 0:
        f = k // 3
        if falive[f] and (F[f, 0] == b or F[f, 1] == b or F[f, 2] == b):
            return True
        k = nxt[k]
    return False


@kernel(cache=True)
def _unit(x, y, z):  # pragma: no cover - compiled
    n = np.sqrt(x * x + y * y + z * z)
    if n <= 1e-300:
        return 0.0, 0.0, 0.0, 0.0
    return x / n, y / n, z / n, n


@kernel(cache=True)
def _face_quality(f, F, V):  # pragma: no cover - compiled
    i, j, k = F[f, 0], F[f, 1], F[f, 2]
    return triangle_quality(V[i, 0], V[i, 1], V[i, 2], V[j, 0], V[j, 1], V[j, 2],
                            V[k, 0], V[k, 1], V[k, 2])


@kernel(cache=True)
def _flap(u, o, F, head, nxt, falive):  # pragma: no cover - compiled
    """(f1, c1, f2, c2): the live faces (u, o, a) and (o, u, b) of edge (u, o) with u's
    corner in each; all -1 unless there is exactly one of each."""
    f1 = f2 = -1
    c1 = c2 = -1
    k = head[u]
    while k >= 0:
        f = k // 3
        c = k % 3
        if falive[f]:
            if F[f, (c + 1) % 3] == o:
                if f1 >= 0:
                    return -1, -1, -1, -1
                f1, c1 = f, c
            elif F[f, (c + 2) % 3] == o:
                if f2 >= 0:
                    return -1, -1, -1, -1
                f2, c2 = f, c
        k = nxt[k]
    if f1 < 0 or f2 < 0:
        return -1, -1, -1, -1
    return f1, c1, f2, c2


@kernel(cache=True)
def _diagonals_within(u, o, a, b, V, max_gap):  # pragma: no cover - compiled
    """The diagonals (u, o) and (a, b) pass within ``max_gap`` of each other:
    |det(o-u, a-u, b-u)| / |(o-u) x (b-a)| (False where they are parallel)."""
    ex, ey, ez = V[o, 0] - V[u, 0], V[o, 1] - V[u, 1], V[o, 2] - V[u, 2]
    ax, ay, az = V[a, 0] - V[u, 0], V[a, 1] - V[u, 1], V[a, 2] - V[u, 2]
    bx, by, bz = V[b, 0] - V[u, 0], V[b, 1] - V[u, 1], V[b, 2] - V[u, 2]
    dx, dy, dz = bx - ax, by - ay, bz - az
    cx, cy, cz = ey * dz - ez * dy, ez * dx - ex * dz, ex * dy - ey * dx
    cross = np.sqrt(cx * cx + cy * cy + cz * cz)
    vol = abs(ex * (ay * bz - az * by) - ey * (ax * bz - az * bx) + ez * (ax * by - ay * bx))
    return cross > 1e-300 and vol <= max_gap * cross


@kernel(cache=True)
def try_flip(u, o, V, F, head, tail, nxt, falive, locked, mark, tag, buf, min_cos,
             max_gap, below):  # pragma: no cover - compiled
    """Flip edge (u, o) where the rules above allow it; True when flipped."""
    f1, c1, f2, c2 = _flap(u, o, F, head, nxt, falive)
    if f1 < 0:
        return False
    a = F[f1, (c1 + 2) % 3]
    b = F[f2, (c2 + 1) % 3]
    if a == b or locked[u] or locked[o] or locked[a] or locked[b]:
        return False
    q1, n1x, n1y, n1z = _face_quality(f1, F, V)
    q2, n2x, n2y, n2z = _face_quality(f2, F, V)
    if min(q1, q2) >= below:
        return False
    if _adjacent(a, b, F, head, nxt, falive):
        return False
    if ring(u, F, head, nxt, falive, mark, tag, buf) < 4:
        return False
    if ring(o, F, head, nxt, falive, mark, tag, buf) < 4:
        return False
    n1x, n1y, n1z, l1 = _unit(n1x, n1y, n1z)
    n2x, n2y, n2z, l2 = _unit(n2x, n2y, n2z)
    if l1 <= 0 or l2 <= 0 or n1x * n2x + n1y * n2y + n1z * n2z < min_cos:
        return False
    if not _diagonals_within(u, o, a, b, V, max_gap):
        return False
    # The new faces (u, b, a) and (o, a, b).
    p1, m1x, m1y, m1z = triangle_quality(V[u, 0], V[u, 1], V[u, 2], V[b, 0], V[b, 1], V[b, 2],
                                 V[a, 0], V[a, 1], V[a, 2])
    p2, m2x, m2y, m2z = triangle_quality(V[o, 0], V[o, 1], V[o, 2], V[a, 0], V[a, 1], V[a, 2],
                                 V[b, 0], V[b, 1], V[b, 2])
    if min(p1, p2) < min(q1, q2) + GAIN:
        return False
    sx, sy, sz, ls = _unit(n1x + n2x, n1y + n2y, n1z + n2z)
    m1x, m1y, m1z, k1 = _unit(m1x, m1y, m1z)
    m2x, m2y, m2z, k2 = _unit(m2x, m2y, m2z)
    if ls <= 0 or k1 <= 0 or k2 <= 0:
        return False
    if min(m1x * sx + m1y * sy + m1z * sz, m2x * sx + m2y * sy + m2z * sz) < min_cos:
        return False
    # f1 (u, o, a) -> (u, b, a); f2 (o, u, b) -> (o, a, b): each moves one corner's node.
    F[f1, (c1 + 1) % 3] = b
    _move(3 * f1 + (c1 + 1) % 3, o, b, head, tail, nxt)
    F[f2, c2] = a
    _move(3 * f2 + c2, u, a, head, tail, nxt)
    return True


@kernel(cache=True)
def flip_all(V, F, head, tail, nxt, falive, locked, mark, tag, min_cos, max_gap, below,
             max_passes):  # pragma: no cover - compiled
    """Passes over every edge with :func:`try_flip` until one flips nothing (at most
    ``max_passes``); returns the number of flips."""
    buf = np.empty(RING, np.int64)
    flips = 0
    for _ in range(max_passes):
        done = 0
        for f in range(F.shape[0]):
            for c in range(3):
                u, o = F[f, c], F[f, (c + 1) % 3]
                if falive[f] and u < o and try_flip(u, o, V, F, head, tail, nxt, falive, locked,
                                                    mark, tag, buf, min_cos, max_gap, below):
                    done += 1
        flips += done
        if done == 0:
            break
    return flips
