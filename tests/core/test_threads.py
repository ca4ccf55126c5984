"""set_threads pins torch's pool and parallel_for's, also on the first call of a fresh process,
and the renderer never starts numba's own pool (its OpenMP layer would reset the thread count
torch shares; its ``prange`` kernels take twice as long to compile)."""
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import numpy as np, torch
import numba.np.ufunc.parallel as numba_pool
from core.runtime.threads import set_threads, threads
from core.render import warm_up
assert set_threads(1) == 1
warm_up(torch.device("cpu"), antialias=True)      # runs the renderer's kernels
from core.spatial.closest import ClosestPointIndex
from core.mesh.primitives import icosphere
v, f = icosphere(3)
ClosestPointIndex(v, f).query(np.random.default_rng(0).normal(size=(5000, 3)))
print(torch.get_num_threads(), threads(), numba_pool._is_initialized)
"""


@pytest.mark.slow
def test_set_threads_first_call_pins_torch_and_ours():
    out = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["1", "1", "False"], out.stdout


def test_parallel_for_covers_the_range_once_and_raises_errors():
    """Every index of the range in exactly one piece, whatever the pieces and threads (more
    threads than cores are capped); a failing piece's error reaches the caller after the
    other pieces are done."""
    import numpy as np
    import pytest
    from numba import njit

    from core.runtime.threads import parallel_for

    @njit(nogil=True)
    def mark(out, lo, hi):
        for i in range(lo, hi):
            out[i] += 1 + i

    for n, parts, workers in [(0, None, None), (1, None, None), (7, 3, 2), (1000, None, 8),
                              (1000, 1000, 2), (5, 50, None)]:
        out = np.zeros(n, np.int64)
        parallel_for(mark, n, out, parts=parts, workers=workers)
        assert np.array_equal(out, 1 + np.arange(n))

    done = []

    def fail(lo, hi):
        done.append((lo, hi))
        if lo == 0:
            raise ValueError("piece 0")

    with pytest.raises(ValueError, match="piece 0"):
        parallel_for(fail, 8, parts=4, workers=2)
    assert sorted(done) == [(0, 2), (2, 4), (4, 6), (6, 8)]
