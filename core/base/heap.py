"""A binary min-heap of edge-collapse candidates in flat arrays, with lazy deletion (numba).

An entry is ``cost[i]`` and ``item[i] = (u, v, stamp_u, stamp_v)``: the collapse of edge
(u, v) as evaluated when both vertices had those stamps. Whoever changes a vertex's
neighbourhood bumps its stamp, so stale entries are recognised when popped
(:func:`is_current`) instead of being searched for and removed.
"""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel


def new_heap(capacity: int) -> tuple[np.ndarray, np.ndarray]:
    """Empty storage: (cost (capacity,), item (capacity, 4))."""
    return np.empty(max(16, capacity)), np.empty((max(16, capacity), 4), np.int64)


@kernel(cache=True)
def _swap(cost, item, i, j):  # pragma: no cover - compiled
    c = cost[i]
    cost[i] = cost[j]
    cost[j] = c
    for k in range(4):
        t = item[i, k]
        item[i, k] = item[j, k]
        item[j, k] = t


@kernel(cache=True)
def _less(cost, item, i, j):  # pragma: no cover - compiled
    """Order by cost, ties by (u, v): the same input always pops in the same order."""
    if cost[i] != cost[j]:
        return cost[i] < cost[j]
    if item[i, 0] != item[j, 0]:
        return item[i, 0] < item[j, 0]
    return item[i, 1] < item[j, 1]


@kernel(cache=True)
def _sift_down(cost, item, size, i):  # pragma: no cover - compiled
    while True:
        a = 2 * i + 1
        if a >= size:
            return
        b = a + 1
        m = b if (b < size and _less(cost, item, b, a)) else a
        if not _less(cost, item, m, i):
            return
        _swap(cost, item, m, i)
        i = m


@kernel(cache=True)
def push(cost, item, size, c, u, v, su, sv):  # pragma: no cover - compiled
    """Add an entry (the caller keeps ``size < len(cost)``); returns the new size."""
    i = size
    cost[i] = c
    item[i, 0] = u
    item[i, 1] = v
    item[i, 2] = su
    item[i, 3] = sv
    while i > 0:
        p = (i - 1) >> 1
        if not _less(cost, item, i, p):
            break
        _swap(cost, item, i, p)
        i = p
    return size + 1


@kernel(cache=True)
def pop(cost, item, size):  # pragma: no cover - compiled
    """Remove the smallest entry, which the caller has read at index 0; returns the new size."""
    size -= 1
    if size > 0:
        _swap(cost, item, np.int64(0), size)   # np.int64: a literal 0 compiles them again
        _sift_down(cost, item, size, np.int64(0))
    return size


@kernel(cache=True)
def is_current(item, i, stamp, alive):  # pragma: no cover - compiled
    u, v = item[i, 0], item[i, 1]
    return alive[u] and alive[v] and stamp[u] == item[i, 2] and stamp[v] == item[i, 3]


@kernel(cache=True)
def compact(cost, item, size, stamp, alive):  # pragma: no cover - compiled
    """Drop every stale entry and restore the heap order; returns the new size."""
    n = 0
    for i in range(size):
        if is_current(item, i, stamp, alive):
            cost[n] = cost[i]
            for k in range(4):
                item[n, k] = item[i, k]
            n += 1
    for i in range(n // 2 - 1, -1, -1):
        _sift_down(cost, item, n, i)
    return n
