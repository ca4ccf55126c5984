"""Per-slot gradient buffers of the renderer's backward kernels: slot k owns the k-th contiguous
block of image rows, and the slots are summed in a fixed order, so results do not depend on
the number of threads and no two threads ever write the same memory."""
from __future__ import annotations

import numpy as np

from ..runtime.jit import kernel
from ..runtime.threads import parallel_for

SLOTS = 8
"""Gradient accumulation slots (fixed, so results are independent of the thread count)."""


@kernel(nogil=True, error_model="numpy")
def reduce_slots(buf, out, lo, hi):
    """out[lo:hi] (N, C) <- buf[:, lo:hi] (K, N, C) summed over slots in slot order (deterministic)."""
    for i in range(lo, hi):
        for j in range(buf.shape[2]):
            s = 0.0
            for k in range(buf.shape[0]):
                s += buf[k, i, j]
            out[i, j] = s
    return 0


_POOL: dict = {}


def slot_buffer(name: str, n: int, dtype, width: int = 3) -> np.ndarray:
    """A reused (SLOTS, n, width) scratch array (the kernels zero their own slot): saves page
    faults on every backward."""
    key = (name, n, width, np.dtype(dtype).str)
    buf = _POOL.get(key)
    if buf is None:
        for k in [k for k in _POOL if k[0] == name]:
            del _POOL[k]
        buf = _POOL[key] = np.empty((SLOTS, n, width), dtype=dtype)
    return buf


def reduce(buf: np.ndarray) -> np.ndarray:
    out = np.empty(buf.shape[1:], dtype=buf.dtype)
    parallel_for(reduce_slots, buf.shape[1], buf, out)
    return out
