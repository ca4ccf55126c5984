"""How fast this machine runs a construction's kind of work, relative to the machine the time
estimate was fitted on (``core.construct.estimate``): a short probe, timed once per process.

The probe does a little of what a construction spends its time on, none of it compiled on
first use (a cold kernel cache would time the compiler): a sort and a scatter-add (the
base builder's and the samples' bookkeeping), sparse matrix-vector products (the fit's conjugate
gradients) and float32 matrix products on torch's thread pool (the renderer's parallel part,
on the cores the run will use). The best of three repeats is taken, so a busy moment does not
make the machine look slow. ``REFERENCE_SECONDS`` is the probe's time on the estimate's
machine; the speed is that over this machine's time (2: twice as fast).
"""
from __future__ import annotations

import time

import numpy as np

# The probe's best time on the machine the estimate's coefficients were fitted on (2 cores,
# AMD EPYC, 24 GB; docs/results.md, eleventh session).
REFERENCE_SECONDS = 0.031
_REPEATS = 3
_cached: float | None = None


def probe_seconds() -> float:
    """The best wall time of :data:`_REPEATS` runs of the probe (about 0.03 s each here)."""
    import scipy.sparse as sp
    import torch

    rng = np.random.default_rng(0)
    keys = rng.random(1 << 18)
    n = 1 << 17
    rows = np.repeat(np.arange(n), 7)
    cols = (rows + rng.integers(-50, 50, rows.size)) % n
    A = sp.csr_matrix((rng.random(rows.size), (rows, cols)), shape=(n, n))
    x = rng.random(n)
    a = torch.rand(256, 256, generator=torch.Generator().manual_seed(0))
    best = np.inf
    for _ in range(_REPEATS):
        t0 = time.perf_counter()
        order = np.argsort(keys)
        np.add.at(np.zeros(1 << 16), order & 0xFFFF, keys)
        y = x
        for _ in range(20):
            y = A @ y
            y /= np.abs(y).max()
        b = a
        for _ in range(70):
            b = torch.tanh(a @ b)
        best = min(best, time.perf_counter() - t0)
    return float(best)


def machine_speed() -> float:
    """This machine's speed relative to the estimate's (probed on the first call, then
    remembered; within [0.05, 20])."""
    global _cached
    if _cached is None:
        _cached = float(np.clip(REFERENCE_SECONDS / max(probe_seconds(), 1e-9), 0.05, 20.0))
    return _cached
