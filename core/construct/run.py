"""``construct``: the one entry point of a micro-mesh construction (method §2–§5).

Base offsets and micro-displacements are optimised against rendered images of the reference,
progressively subdividing with adaptive level of detail. Everything inside runs in the
unit-sphere frame of the reference; inputs and the result are in the caller's frame. The
phases: setup (:mod:`.frame`, :mod:`.scene`), initial baking, the loop (:mod:`.step`,
:mod:`.schedule`, :mod:`.choose_levels`), final levels (:mod:`.choose_levels`),
bounds and metrics (:mod:`.finalise`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

from ..render.cameras import Cameras
from ..lod import effective_micro_triangles
from ..runtime.memory import keep_large_allocations, map_large_allocations, release_memory
from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from ..settings.fields import ConstructSettings
from ..runtime.determinism import deterministic
from ..runtime.machine import available_memory_bytes, peak_resident_bytes
from ..runtime.threads import set_threads
from .estimate import check_fits, estimate
from .finalise import finalise
from .frame import (check_inputs, check_reference, device as torch_device, fixed_levels,
                    oriented, prepare_base)
from .step import optimise
from .params import Parameters
from .schedule import Schedule
from .start import initial_micromesh, start_run
from .state import RunState
from .held import held_vertices
from .kernels import BASE, FIRST_ITERATION, Kernels
from .views import check_views
from .types import ConstructError, ConstructResult, Progress


def construct(reference: TriMesh, base: TriMesh | None, cameras: Cameras | None,
              settings: ConstructSettings,
              progress: Callable[[Progress], None] | None = None,
              should_stop: Callable[[], bool] | None = None,
              levels: np.ndarray | None = None) -> ConstructResult:
    """Build a micro-mesh of ``reference`` on ``base`` (both in the caller's frame).

    ``base`` None: the settings' base (``core.base.base_for``) is built first (phase "base");
    its report is ``metrics["base"]``. The reference's winding is made consistent first
    (``core.mesh.orient``). ``metrics["warnings"]`` lists, in words, which faces were turned, how the
    base's topology differs from the reference's and where the base builder stopped short.

    ``cameras`` (caller's frame) or None for ``settings.n_views`` Fibonacci cameras. Raises
    :class:`ConstructCancelled` within one iteration of ``should_stop()`` returning True.

    ``levels`` (one per base face, 0..5; the artist's per-face override): balanced, then kept
    fixed. No subdivision schedule and no LOD; the base is frozen (the result's base vertices
    are the input's); displacements start from projection baking at those levels and are
    optimised as usual (reparameterisation, L_sv, rendering loss) within the settings' budget.

    Large freed buffers stay in the heap while the optimiser runs and have mappings of their
    own after it (``core.runtime.memory``; the policies stay set for the process); the free
    heap goes back to the OS when it returns. On CUDA, torch's
    deterministic algorithms are on while it runs (``core.runtime.determinism``).
    """
    keep_large_allocations()
    try:
        with deterministic(torch_device(settings.validate().device)):
            return _construct(reference, base, cameras, settings, progress, should_stop, levels)
    finally:
        release_memory()


def _construct(reference, base, cameras, settings, progress, should_stop,
               levels) -> ConstructResult:
    s = settings.validate()
    if base is None:
        check_reference(reference)
        if levels is not None:
            raise ConstructError("fixed levels need the base mesh they belong to")
    else:
        check_inputs(reference, base)
    guess = estimate(reference.n_faces, s)
    check_fits(guess, available_memory_bytes())
    set_threads(s.threads)
    dev = torch_device(s.device)
    # A fresh checkout's kernels are compiled in processes of their own while the
    # construction goes on (.kernels); the time limit counts from here, the base building
    # included, but not the waits for them, which must not eat it or distort the ETA.
    with Kernels(progress, should_stop) as kernels:
        t_start = time.perf_counter()
        inputs = _inputs(reference, base, s, kernels, progress, should_stop)
        kernels.ready(FIRST_ITERATION)
        _announce(progress, "views")   # the cameras, the reference's images, the first values
        kernels.renderer_ready(dev, s.antialias)
        t_start += kernels.waited
        run = _run_state(inputs, cameras, s, dev, levels, should_stop, progress)
        # The loop leaves time for the fit and the metrics; polishing takes what is left of
        # the time limit (it stops at the deadline), but the time left shown counts it.
        reserve = guess.phases["fit"] + guess.phases["metrics"]
        run.finish_estimate_s = reserve + guess.phases["polish"]
        schedule = Schedule(s, t_start, fixed_levels=run.fixed is not None, finish_s=reserve)
        mm, it_done = _optimise(run, schedule, progress)
        map_large_allocations()
        # The fit's kernels, where the loop ended before they were compiled: the wait moves
        # the deadline of the fit's optional passes and is not counted in the run's time.
        late = kernels.ready(None)
        run.deadline += late
        result = finalise(run, mm, inputs.reference, inputs.base, t_start + late, it_done,
                          schedule.stopped_early)
        return _reported(result, run, inputs, guess, progress)


@dataclass
class _Inputs:
    """The reference with its winding made consistent, the base (caller's frame), the base
    builder's report (None for a given base) and the warnings said so far."""

    reference: TriMesh
    base: TriMesh
    base_report: dict | None
    warnings: list[str]


def _announce(progress, phase: str) -> None:
    if progress is not None:
        progress(Progress(phase, 0, 1, 0.0, float("nan"), float("nan")))


def _inputs(reference, base, s, kernels, progress, should_stop) -> _Inputs:
    """Phases "reference" (loose parts, repeated faces and the winding; seconds on 1M faces)
    and "base" (built once its kernels are compiled, or the given one compared)."""
    _announce(progress, "reference")
    reference, warnings = oriented(reference)
    kernels.ready(BASE)
    base, report, base_warnings = prepare_base(reference, base, s, progress, should_stop)
    return _Inputs(reference, base, report, warnings + base_warnings)


def _run_state(inputs, cameras, s, dev, levels, should_stop, progress) -> RunState:
    """The run in the reference's unit frame: its scene, the artist's levels and the held
    base vertices (the view checks' warnings go to ``inputs``)."""
    fixed = fixed_levels(inputs.base, levels) if levels is not None else None
    torch.manual_seed(s.seed)
    t_setup = time.perf_counter()
    run = start_run(inputs.reference, inputs.base, cameras, s, dev, should_stop, fixed)
    run.progress = progress
    if s.hold_exact_base and fixed is None:
        run.held_in_fit, run.held = held_vertices(run.base, run.scene.ref)
        run.notes["held_vertices"] = {"optimiser": int(run.held.sum()),
                                      "fit": int(run.held_in_fit.sum())}
    if cameras is not None:
        inputs.warnings += check_views(run.scene.ref, run.scene.cams, dev)
    run.timer.times["setup"] = time.perf_counter() - t_setup
    if inputs.base_report is not None:
        run.timer.times["base"] = inputs.base_report["time_s"]
    run.check_stop()
    return run


def _optimise(run: RunState, schedule: Schedule, progress) -> tuple[MicroMesh, int]:
    """The reference's images, the first values and the loop: (the micro-mesh, iterations
    done). The optimiser's state (its solver, moments, the renderer's last buffers) and the
    training images are freed on return, before the fit's peak."""
    with run.timer.phase("reference_images"):
        target_all = run.scene.images(run.scene.cams)
    with run.timer.phase("init"):
        mm = initial_micromesh(run)
        params = Parameters(run.base, mm, run.s, run.device, frozen_base=run.fixed is not None,
                            held=run.held)
    if run.fixed is not None:
        run.event(iteration=0, fixed_levels=True,
                  micro_triangles=effective_micro_triangles(run.fixed, run.base))
    run.deadline = schedule.deadline
    it_done = optimise(run, params, schedule, target_all, progress)
    run.check_stop()
    with run.timer.phase("finalize"):
        return params.micromesh(), it_done


def _reported(result: ConstructResult, run: RunState, inputs: _Inputs, guess,
              progress) -> ConstructResult:
    """``result`` with the warnings, the estimate, the peak memory and the base's report in
    its metrics, and the "done" progress."""
    result.metrics["warnings"] = inputs.warnings
    result.metrics["estimate"] = {"seconds": guess.seconds, "peak_bytes": guess.peak_bytes}
    result.metrics["peak_memory_bytes"] = peak_resident_bytes()
    if inputs.base_report is not None:
        result.metrics["base"] = inputs.base_report
    if progress is not None:
        h, n_it = run.history, run.s.iterations
        psnr = result.metrics.get("psnr", h["psnr"][-1] if h["psnr"] else 0.0)
        progress(Progress("done", n_it, n_it, h["loss"][-1] if h["loss"] else 0.0, psnr, 0.0))
    return result
