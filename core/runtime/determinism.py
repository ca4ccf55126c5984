"""The same numbers from the same inputs on a GPU.

On CUDA, ``index_add`` and the backward of ``x[index]`` add colliding rows with atomics, in
whatever order the threads arrive: float sums then differ in their last bits from run to run,
and an optimisation that feeds them back drifts apart. torch's deterministic mode selects
sort-based versions of those ops (colliding rows added in a fixed order).
"""
from __future__ import annotations

from contextlib import contextmanager

import torch


@contextmanager
def deterministic(device: torch.device | str):
    """torch's deterministic algorithms for the block on a CUDA device (warnings, not errors,
    for ops that have none); the previous mode afterwards. No-op on other devices."""
    if torch.device(device).type != "cuda":
        yield
        return
    was, warn = torch.are_deterministic_algorithms_enabled(), \
        torch.is_deterministic_algorithms_warn_only_enabled()
    torch.use_deterministic_algorithms(True, warn_only=True)
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(was, warn_only=warn)
