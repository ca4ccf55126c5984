"""The end of a construction: final levels, balance, the least-squares fit of the
displacements (``core.fit``), levels moved to where the fit still misses the reference and
fitted again (``choose_levels.residual_exchange``; kept only where that lowers the shading
error), bounds folded into the base and the directions (what a file holds:
``core.bounds.baked``; those of least shell volume, with the displacements fitted again under
them, where the image error rises by 1 % at most), metrics, and the result in the caller's
frame."""
from __future__ import annotations

import time

import numpy as np

from ..bounds import baked, lp_bounds, micromesh_shell_volume, tight_bounds, unit_bounds
from ..mesh import TriMesh
from ..micromesh import MicroMesh
from ..microtopology import balance_levels
from ..fit import surface_errors
from .choose_levels import final_levels
from .evaluate import evaluate
from .fitting import fit_rounds, fitted
from .frame import to_caller_frame
from .scene import face_errors
from .state import RunState
from .types import ConstructResult


def finalise(run: RunState, mm: MicroMesh, reference: TriMesh, base: TriMesh,
             t_start: float, iterations: int, stopped_early: bool) -> ConstructResult:
    """The result from the optimiser's micro-mesh ``mm`` (unit frame)."""
    mm = final_levels(run, mm)
    with run.timer.phase("finalize"):
        mm = mm.with_levels(balance_levels(run.base, mm.levels))
    samples, error = None, None
    if run.s.final_fit:
        run.check_stop()
        run.announce("fit")
        mm, samples, error = fitted(run, mm)
    bounds = None
    if run.s.fold_bounds and run.fixed is None:  # what a file holds (not: a frozen base)
        run.check_stop()
        run.announce("bounds")
        mm, bounds = folded(run, mm, samples, error), unit_bounds(mm.base.n_vertices)
    with run.timer.phase("finalize"):
        bounds = tight_bounds(mm) if bounds is None else bounds
    run.check_stop()
    construct_time = time.perf_counter() - t_start
    metrics: dict = {}
    if run.s.compute_metrics:
        run.announce("metrics")
        with run.timer.phase("metrics"):
            metrics = evaluate(mm, run.scene.ref, run.s, bounds, run.device)
    metrics.update(time_s=construct_time, iterations=iterations, stopped_early=stopped_early,
                   fixed_levels=run.fixed is not None)
    out, b = to_caller_frame(mm, bounds, run.norm)
    if run.fixed is not None:        # the base was frozen: hand back the caller's vertices
        out = out.with_base_positions(np.asarray(base.vertices, dtype=np.float64))
    metrics.update(run.notes)
    return ConstructResult(out, b, run.gains, metrics, dict(run.timer.times), run.history,
                           run.s, run.norm, mm)


# The thinner shell is kept where the image error rises by at most this factor (armadillo:
# +0.07 % for a quarter less shell, the same PSNR under the judge).
_IMAGE_TOLERANCE = 1.01


def folded(run: RunState, mm: MicroMesh, samples, error: float | None = None) -> MicroMesh:
    """``mm`` with bounds folded into its base and directions (``core.bounds.baked``): its
    tight bounds, or, after a fit (``samples``) and with ``lp_bounds``, the least-volume
    bounds (``core.bounds.lp_bounds``) with the displacements fitted again under them (baking
    such bounds moves micro-vertices: neighbours' bounds differ more) and then the tight
    bounds of the result, which are nearly unit and bake almost exactly. That second way is
    kept where its image error (the LOD views' L1, ``scene.face_errors``) is at most 1 %
    larger (``_IMAGE_TOLERANCE``); the samples' shading error, recorded beside it, misjudged
    it both ways (counter_cad, beast); ``run.notes["lp_bounds"]`` says what happened.
    ``error``: mm's shading error on ``samples``, where the caller knows it."""
    with run.timer.phase("finalize"):
        tight = baked(mm, tight_bounds(mm))
    if not run.s.lp_bounds or samples is None:
        return tight
    with run.timer.phase("bounds"):
        least = baked(mm, lp_bounds(mm))
    with run.timer.phase("fit"):
        least = fit_rounds(run, least, samples, rounds=1)
    with run.timer.phase("bounds"):
        least = baked(least, tight_bounds(least))
        # tight holds mm's micro-surface (to rounding): mm's shading error where known
        before = surface_errors(tight, samples)[1].sum() if error is None else error
        after = surface_errors(least, samples)[1].sum()
        shells = [micromesh_shell_volume(m, unit_bounds(m.base.n_vertices))
                  for m in (tight, least)]
        images = [face_errors(m, run.scene, run.lod_cams, "lod", run.s, run.ref_tree).sum()
                  for m in (tight, least)]
    keep = bool(images[1] <= _IMAGE_TOLERANCE * images[0])
    run.notes["lp_bounds"] = {"kept": keep, "shading_error_before": float(before),
                              "shading_error_after": float(after),
                              "image_error_before": float(images[0]),
                              "image_error_after": float(images[1]),
                              "shell_before": float(shells[0]), "shell_after": float(shells[1])}
    return least if keep else tight
