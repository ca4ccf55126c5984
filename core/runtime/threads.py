"""One place that pins the native thread pools (torch, numba) to a core count.

Several native pools in one process oversubscribe a small machine; every entry point (tests,
benchmarks, batch, the Blender add-on preferences) calls :func:`set_threads` instead of
touching the pools itself.
"""
from __future__ import annotations

import os


def default_threads() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def set_threads(n: int | None = None) -> int:
    """Pin torch's and numba's pools to ``n`` threads (default: the usable cores); returns n."""
    n = default_threads() if not n or n < 1 else int(n)
    n = min(n, default_threads())
    # numba first: its first call launches numba's OpenMP layer, which resets the OpenMP
    # thread count that torch shares (torch would silently run on all cores, and its float
    # reductions would then sum in a different order than on later calls).
    try:
        import numba

        numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))
    except ImportError:
        pass
    import torch

    torch.set_num_threads(n)
    return n
