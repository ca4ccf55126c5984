"""The fit stage of a construction's end (``core.fit``): the displacements fitted to the
reference, levels moved to where the fit still misses it and fitted again
(``choose_levels.residual_exchange``; kept only where that lowers the shading error), and
the base vertices fitted with the displacements (kept where that lowers the shading error
without widening the shell)."""
from __future__ import annotations

import numpy as np

from ..bounds import micromesh_shell_volume, tight_bounds
from ..fit import fit_micromesh, fit_samples, surface_errors
from ..micromesh import MicroMesh
from .choose_levels import residual_exchange
from .state import RunState


def fitted(run: RunState, mm: MicroMesh) -> tuple[MicroMesh, tuple]:
    """``mm`` with its displacements fitted to the reference (``core.fit``); then, with a
    budget, levels moved to where the fit still misses it and fitted again. The moved levels
    are kept only where they lower the shading error (squared normal differences) of the same
    reference samples: where the residual model misjudges a mesh (smooth ones, whose residual
    falls faster than it assumes), the first fit stays. ``run.notes["residual_lod"]`` says
    what happened. Last, the base vertices are fitted with the displacements
    (``fit_base_stiffness``; not where the base is frozen). Returns the micro-mesh and the
    reference samples it was fitted to."""
    ref = run.scene.ref
    with run.timer.phase("fit"):
        samples = fit_samples(mm, ref)
        mm = fit_rounds(run, mm, samples)
    error = None                # the shading error of (mm, samples), where already known
    if run.s.residual_lod > 0 and run.fixed is None and run.cost is not None:
        run.check_stop()
        run.announce("residual_lod")
        mm, samples, error = _exchanged(run, mm, samples)
    if run.s.fit_base_stiffness > 0 and run.fixed is None:
        run.check_stop()
        run.announce("base_fit")
        mm = _base_moved(run, mm, samples, error)
    return mm, samples


# The base may move where the shell grows by at most this factor.
_SHELL_GROWTH = 1.1


def _base_moved(run: RunState, mm: MicroMesh, samples, before: float | None = None
                ) -> MicroMesh:
    """One fit round with the base vertices as unknowns, kept where it lowers the shading
    error (``before``: mm's, where the caller knows it) without widening the shell by more
    than a tenth (on parts thinner than the samples' spacing a base vertex can be pulled
    across to the far side); ``run.notes["base_fit"]`` says what happened."""
    with run.timer.phase("fit"):
        moved = fit_rounds(run, mm, samples, run.s.fit_base_stiffness, rounds=1)
        if before is None:
            before = surface_errors(mm, samples)[1].sum()
        after = surface_errors(moved, samples)[1].sum()
        shells = [micromesh_shell_volume(m, tight_bounds(m)) for m in (mm, moved)]
    keep = bool(after < before and shells[1] <= _SHELL_GROWTH * shells[0])
    run.notes["base_fit"] = {"kept": keep, "shading_error_before": float(before),
                             "shading_error_after": float(after),
                             "shell_before": float(shells[0]), "shell_after": float(shells[1])}
    return moved if keep else mm


def _exchanged(run: RunState, mm: MicroMesh, samples) -> tuple[MicroMesh, tuple, float | None]:
    """The residual exchange of levels, fitted, kept where it lowers the shading error; the
    micro-mesh kept, the samples that fit it and, where it is the first, its shading error on
    them."""
    with run.timer.phase("residual_lod"):
        dist, normal = surface_errors(mm, samples)
        new = residual_exchange(run, mm.levels, dist)
    if np.array_equal(new, mm.levels):
        return mm, samples, float(normal.sum())
    with run.timer.phase("fit"):
        moved = mm.with_levels(new)
        moved_samples = fit_samples(moved, run.scene.ref)
        moved = fit_rounds(run, moved, moved_samples)
    with run.timer.phase("residual_lod"):
        after = surface_errors(moved, samples)[1].sum()
    keep = bool(after < normal.sum())
    run.notes["residual_lod"] = {"faces_up": int((new > mm.levels).sum()),
                                 "faces_down": int((new < mm.levels).sum()), "kept": keep,
                                 "shading_error_before": float(normal.sum()),
                                 "shading_error_after": float(after)}
    return (moved, moved_samples, None) if keep else (mm, samples, float(normal.sum()))


def fit_rounds(run: RunState, mm: MicroMesh, samples, base_stiffness: float = 0.0,
         rounds: int = 2) -> MicroMesh:
    """The least-squares fit with the run's settings (the base vertices held with
    ``base_stiffness``, fixed at 0); one round suffices from an already fitted ``mm``."""
    return fit_micromesh(mm, run.scene.ref, run.s.fit_smoothness, rounds, samples=samples,
                         slopes=run.s.fit_slopes, base_stiffness=base_stiffness)
