"""The listed kernels a construction's cache lacks, compiled while it goes on
(``runtime.compiling``): the construction waits for those of each stage before the stage,
reporting phase "compiling kernels", and its time limit does not count the waits."""
from __future__ import annotations

import time
from typing import Callable, Collection

from ..render import warm_up
from ..runtime import compiling
from .types import ConstructCancelled, Progress

BASE = ("reference", "base")
"""The phases whose kernels the base builder needs (the closest points of its report too)."""
FIRST_ITERATION = ("views", "optimize")
"""The phases whose kernels the reference images and the optimiser need."""


class Kernels:
    """Compiling processes started (nothing where the cache holds every listed kernel or
    there is one core) and the seconds the construction has waited for them."""

    def __init__(self, progress: Callable | None, should_stop: Callable[[], bool] | None):
        self.progress, self.should_stop = progress, should_stop
        self.compiling = compiling.start()
        self.waited = 0.0

    def ready(self, phases: Collection[str] | None) -> float:
        """Wait until the kernels first called in ``phases`` (None: all) are compiled; returns
        the seconds this call waited."""
        if self.compiling is None:
            return 0.0
        report = None if self.progress is None else (
            lambda done, total: self.progress(Progress("compiling kernels", done, total,
                                                       float("nan"), float("nan"),
                                                       float("nan"))))
        waited = self.compiling.wait(phases, report, self.should_stop)
        self.waited += waited
        if self.should_stop is not None and self.should_stop():
            raise ConstructCancelled("construction cancelled")
        return waited

    def renderer_ready(self, device, antialias: bool) -> None:
        """The renderer's kernels loaded (``render.warm_up``), its time counted as waited."""
        t = time.perf_counter()
        warm_up(device, antialias=antialias)
        self.waited += time.perf_counter() - t

    def __enter__(self) -> "Kernels":
        return self

    def __exit__(self, *exc) -> None:
        """The processes still running end (a cancel, a failure)."""
        if self.compiling is not None:
            self.compiling.close()
            self.compiling = None
