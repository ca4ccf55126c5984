"""core.runtime.memory: with the heap policy on, a freed image-sized array is reused without page
faults, and release_memory hands the free heap back (glibc only; fresh processes, since the
policy is process-wide)."""
import subprocess
import sys
from pathlib import Path

import pytest

from core.runtime.memory import _glibc

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import resource, sys
import numpy as np
from core.runtime.memory import keep_large_allocations, release_memory

def faults_of_fill():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    a = np.empty(96 * 2**20, np.uint8)
    a.fill(1)
    del a
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

def rss_mb():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096 / 2**20

on = sys.argv[1] == "on"
if on:
    assert keep_large_allocations()
faults_of_fill()
second = faults_of_fill()
kept = rss_mb()
release_memory()
print(second, kept, rss_mb())
"""


def _run(mode: str) -> tuple[int, float, float]:
    out = subprocess.run([sys.executable, "-c", SCRIPT, mode], cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    second, kept, released = out.stdout.split()
    return int(second), float(kept), float(released)


@pytest.mark.skipif(_glibc() is None, reason="the heap policy needs glibc")
@pytest.mark.slow
def test_heap_policy_reuses_large_buffers_and_releases_them():
    off_faults, off_kept, _ = _run("off")
    on_faults, on_kept, on_released = _run("on")
    assert off_faults > 40  # default glibc: a fresh mapping, faulted in again (hugepages or not)
    assert on_faults < 10  # policy on: the same heap memory, no new faults
    assert on_kept > on_released + 64  # the 96 MB stayed in the heap until release_memory
