"""One place that pins the thread pools (torch's and ours to a core count, BLAS to one), and
:func:`parallel_for`, which runs a compiled kernel over parts of a range on our pool.

Several native pools in one process oversubscribe a small machine; every entry point (tests,
benchmarks, batch, the Blender add-on preferences) calls :func:`set_threads` instead of
touching the pools itself.

The kernels run in parallel through :func:`parallel_for` rather than numba's ``prange``: a
``prange`` kernel takes numba about twice as long to compile (parallel lowering), which a
fresh install pays before its first construction. Our kernels release the GIL
(``kernel(nogil=True)``), so threads of one process run them side by side.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Callable

_THREADS: int | None = None                  # set_threads' count (None: the usable cores)
_POOL: ThreadPoolExecutor | None = None
_LOCK = threading.Lock()


def default_threads() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def set_threads(n: int | None = None) -> int:
    """Pin torch's pool and :func:`parallel_for`'s to ``n`` threads (default: the usable
    cores), and the BLAS libraries' to one (:func:`pin_blas`); returns n. (numba's own pool is
    never started: no kernel uses ``prange``. Were it started, its OpenMP layer would reset
    the thread count torch shares.)"""
    global _THREADS
    n = default_threads() if not n or n < 1 else int(n)
    n = min(n, default_threads())
    _THREADS = n
    import torch

    torch.set_num_threads(n)
    pin_blas()
    return n


def pin_blas() -> None:
    """numpy's and scipy's BLAS (OpenBLAS) on one thread, whatever the thread count. Their
    threaded reductions add in an order that follows their thread count, which came from the
    environment (``OMP_NUM_THREADS``, which Ray sets to a task's CPUs), so the same input gave
    other bytes under Ray than in one process. The construction calls BLAS only on small
    arrays: one thread costs it nothing measurable (``tests/blender/test_determinism.py``).
    Without threadpoolctl (an install from before it was pinned) they keep their own. The pin
    is the process's: inside Blender it holds for the session, for numpy's other users too."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return
    import scipy.linalg  # noqa: F401  (loads scipy's own BLAS, so that it is pinned too)

    threadpool_limits(1, user_api="blas")


def threads() -> int:
    """The thread count :func:`parallel_for` uses (:func:`set_threads`'s, else the cores)."""
    return _THREADS or default_threads()


def _pool() -> ThreadPoolExecutor:
    global _POOL
    with _LOCK:
        if _POOL is None:       # sized for any count set later; a call uses at most threads()
            _POOL = ThreadPoolExecutor(default_threads(), thread_name_prefix="micromesh")
        return _POOL


def parallel_for(fn: Callable, n: int, *args, parts: int | None = None,
                 workers: int | None = None) -> None:
    """``fn(*args, lo, hi)`` over ``[0, n)`` cut into ``parts`` contiguous pieces (default: 4
    per thread, for balance) on ``workers`` threads (default :func:`threads`), the caller's
    among them; returns when all are done, raising the first error. ``fn`` must release the
    GIL and write disjoint memory for disjoint pieces; which thread runs a piece must not
    change the result."""
    n = int(n)
    k = max(1, min(workers or threads(), default_threads()))
    parts = max(1, min(n, parts or 4 * k))
    if n <= 0:
        return
    if k == 1 or parts == 1 or threading.current_thread().name.startswith("micromesh"):
        fn(*args, 0, n)       # (from inside a piece, no nesting: the pool could be all busy)
        return
    bounds = [n * i // parts for i in range(parts + 1)]
    pieces = iter(zip(bounds[:-1], bounds[1:]))
    lock = threading.Lock()

    def worker() -> None:   # each thread takes the next piece until none is left
        while True:
            with lock:
                piece = next(pieces, None)
            if piece is None:
                return
            fn(*args, *piece)

    futures = [_pool().submit(worker) for _ in range(min(k, parts) - 1)]
    try:
        worker()
    finally:
        wait(futures)
    for f in futures:
        f.result()
