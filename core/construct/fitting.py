"""The fit stage of a construction's end (``core.fit``): the displacements fitted to the
reference, levels moved to where the fit still misses it and fitted again
(``choose_levels.residual_exchange``; kept only where that lowers the shading error), and
the base vertices fitted with the displacements, then the directions (each kept where that
lowers the shading error without widening the shell)."""
from __future__ import annotations

import numpy as np

from ..bounds import micromesh_shell_volume, tight_bounds
from ..fit import Samples, fit_directions, fit_micromesh, fit_samples, surface_errors
from ..micromesh import MicroMesh
from .choose_levels import residual_exchange
from .state import RunState


def fitted(run: RunState, mm: MicroMesh) -> tuple[MicroMesh, Samples, float | None]:
    """``mm`` with its displacements fitted to the reference (``core.fit``); then, with a
    budget, levels moved to where the fit still misses it and fitted again. The moved levels
    are kept only where they lower the shading error (squared normal differences) of the same
    reference samples: where the residual model misjudges a mesh (smooth ones, whose residual
    falls faster than it assumes), the first fit stays. ``run.notes["residual_lod"]`` says
    what happened. Then the base vertices are fitted with the displacements
    (``fit_base_stiffness``), and last the directions (``fit_directions``), each kept where
    it helps (neither where the base is frozen). Returns the micro-mesh, the reference
    samples it was fitted to and its shading error on them (None where no round measured
    it)."""
    ref = run.scene.ref
    with run.timer.phase("fit"):
        samples = fit_samples(mm, ref)
        mm = fit_rounds(run, mm, samples)
    known = (None, None)        # mm's shading error on the samples and shell, where known
    if run.s.residual_lod > 0 and run.fixed is None and run.cost is not None:
        run.check_stop()
        run.announce("residual_lod")
        mm, samples, error = _exchanged(run, mm, samples)
        known = (error, None)
    if run.s.fit_base_stiffness > 0 and run.fixed is None:
        run.check_stop()
        run.announce("base_fit")
        mm, known = _base_moved(run, mm, samples, known)
    if run.s.fit_directions and run.fixed is None:
        run.check_stop()
        run.announce("direction_fit")
        mm, known = _directions_turned(run, mm, samples, known)
    return mm, samples, known[0]


# A round's result is kept where the shell grows by at most this factor.
_SHELL_GROWTH = 1.1


def _base_moved(run: RunState, mm: MicroMesh, samples, known=(None, None)):
    """One fit round with the base vertices as unknowns, kept where it lowers the shading
    error without widening the shell by more than a tenth (on parts thinner than the samples'
    spacing a base vertex can be pulled across to the far side); ``run.notes["base_fit"]``
    says what happened. ``known`` and the result's second item: see :func:`_kept`."""
    with run.timer.phase("fit"):
        moved = fit_rounds(run, mm, samples, run.s.fit_base_stiffness, rounds=1)
    return _kept(run, "base_fit", mm, moved, samples, known)


def _directions_turned(run: RunState, mm: MicroMesh, samples, known=(None, None)):
    """One fit round with the base directions as unknowns too (``core.fit.fit_directions``),
    then one over the displacements (a direction put back leaves its neighbours' values
    off); kept as the base round is; ``run.notes["direction_fit"]`` says what happened."""
    with run.timer.phase("fit"):
        turned = fit_directions(mm, samples, run.s.fit_smoothness, run.s.fit_slopes)
        turned = fit_rounds(run, turned, samples, rounds=1)
    return _kept(run, "direction_fit", mm, turned, samples, known)


def _kept(run: RunState, note: str, mm: MicroMesh, moved: MicroMesh, samples,
          known=(None, None)) -> tuple[MicroMesh, tuple[float, float]]:
    """(``moved`` where it lowers the shading error of ``samples`` and widens the shell by at
    most ``_SHELL_GROWTH``, else ``mm``; that one's (shading error, shell)), the decision in
    ``run.notes[note]``. ``known``: mm's (shading error, shell) where the caller has them
    (None where not): each is a pass over the samples or the micro-mesh at most."""
    error, shell = known
    with run.timer.phase("fit"):
        if error is None:
            error = float(surface_errors(mm, samples)[1].sum())
        if shell is None:
            shell = micromesh_shell_volume(mm, tight_bounds(mm))
        after = float(surface_errors(moved, samples)[1].sum())
        shell_after = micromesh_shell_volume(moved, tight_bounds(moved))
    keep = bool(after < error and shell_after <= _SHELL_GROWTH * shell)
    run.notes[note] = {"kept": keep, "shading_error_before": error,
                       "shading_error_after": after,
                       "shell_before": float(shell), "shell_after": float(shell_after)}
    return (moved, (after, shell_after)) if keep else (mm, (error, shell))


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
