"""The optimisation loop (method §3–§5): per iteration the subdivisions the schedule has due
(:mod:`.subdivision`, with their level of detail), then one optimiser step (:mod:`.step`) on
a random batch of the training views; the run's history and progress as it goes."""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from .params import Parameters
from .schedule import Schedule
from .state import RunState
from .step import step
from .subdivision import subdivide
from .types import Progress


def optimise(run: RunState, params: Parameters, schedule: Schedule, target,
             progress: Callable[[Progress], None] | None = None) -> int:
    """``run.s.iterations`` iterations, fewer where ``schedule`` runs out of time; ``target``:
    the reference images of ``run.scene.cams`` (the training views). Appends each iteration's
    loss and PSNR to ``run.history``; returns the iterations done."""
    s, cams, h = run.s, run.scene.cams, run.history
    rng = np.random.default_rng(s.seed)
    n_it, views = s.iterations, min(s.views_per_iter, len(cams))
    t_loop, done = time.perf_counter(), 0
    for it in range(n_it):
        run.check_stop()
        if schedule.out_of_time(it):
            break
        for _ in range(schedule.events_due(it)):
            if run.level < s.max_level:
                with run.timer.phase("subdivide"):
                    subdivide(run, params, it)
                run.check_stop()
        with run.timer.phase("optimize"):
            idx = np.sort(rng.choice(len(cams), views, replace=False))
            warm = s.base_warm_up and run.level == 0 and run.fixed is None
            loss, l_render, mse = step(params, s, cams.subset(idx), target[idx], run.h,
                                       schedule.frozen(it), warm)
        p = 10 * np.log10(1.0 / mse) if mse > 0 else float("inf")
        done += 1
        h["iteration"].append(it)
        h["loss"].append(loss)
        h["render"].append(l_render)
        h["psnr"].append(float(p))
        if progress is not None:
            el = time.perf_counter() - t_loop
            progress(Progress("optimize", it + 1, n_it, loss, float(p),
                              schedule.bounded_eta(el / done * (n_it - done))))
    return done
