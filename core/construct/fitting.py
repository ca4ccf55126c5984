"""The fit stage of a construction's end (``core.fit``): the displacements fitted to the
reference, levels moved to where the fit still misses it and fitted again
(``choose_levels.residual_exchange``; kept only where that lowers the shading error), and
the base vertices fitted with the displacements, then the directions, pass after pass (each
kept where that lowers the shading error and keeps the shell within a tenth of where it
was)."""
from __future__ import annotations

import time

import numpy as np

from ..micro.bounds import micromesh_shell_volume, reach, tight_bounds
from ..fit import Samples, fit_directions, fit_micromesh, fit_samples, surface_errors
from ..micro.micromesh import MicroMesh
from .choose_levels import residual_exchange
from .state import RunState


def fitted(run: RunState, mm: MicroMesh) -> tuple[MicroMesh, Samples, float | None]:
    """``mm`` with its displacements fitted to the reference (``core.fit``); then, with a
    budget, levels moved to where the fit still misses it (each face's part of the total
    distance error plus its part of the shading error) and fitted again. The moved levels
    are kept only where they lower the shading error (squared normal differences) of the same
    reference samples: where the residual model misjudges a mesh (smooth ones, whose residual
    falls faster than it assumes), the first fit stays. ``run.notes["residual_lod"]`` says
    what happened. Then the base vertices are fitted with the displacements
    (``fit_base_stiffness``), and the directions turned (``fit_directions``), each kept where
    it lowers the shading error and the shell stays within a tenth of what it was before
    the first of them; the two, ``fit_passes`` times (neither where the base is frozen).
    Returns the micro-mesh, the reference samples it was fitted to and its shading error on
    them (None where no round measured it)."""
    ref = run.scene.ref
    began = time.perf_counter()
    with run.timer.phase("fit"):
        samples = fit_samples(mm, ref)
        mm = fit_rounds(run, mm, samples)
    first = time.perf_counter() - began         # the yardstick of the later stages' times
    error = None                # mm's shading error on the samples, where known
    if run.s.residual_lod > 0 and run.fixed is None and run.cost is not None:
        run.check_stop()
        run.announce("residual_lod")
        if _ends_past_deadline(run, (_EXCHANGE_TIME + _TAIL_TIME) * first):
            run.notes["residual_lod"] = {"kept": False, "cut_by_time_limit": True}
        else:
            mm, samples, error = _exchanged(run, mm, samples)
    if run.fixed is None:
        mm, error = _moving_rounds(run, mm, samples, error, _PASS_TIME * first,
                                   _TAIL_TIME * first)
    return mm, samples, error


# The residual exchange and one pass of the moving rounds take about these multiples of the
# first fit's time (1M and 2M inputs: 1.45-1.6 and 3.05-3.4): where one would end past the
# deadline it is left out (the first fit, the bounds and the metrics always run). The
# bounds' tries, which always run after them, take about the first fit's time (_TAIL_TIME):
# an optional stage must leave that much before the deadline too.
_EXCHANGE_TIME = 1.5
_PASS_TIME = 3.0
_TAIL_TIME = 1.0


def _ends_past_deadline(run: RunState, seconds: float) -> bool:
    return time.perf_counter() + seconds > run.deadline


def _moving_rounds(run: RunState, mm: MicroMesh, samples, error: float | None,
                   first_pass: float, tail: float) -> tuple[MicroMesh, float | None]:
    """The base round and the directions' round (those the settings ask for), ``fit_passes``
    times, each kept by :func:`_kept` with the shell capped at ``_SHELL_GROWTH`` times mm's;
    the micro-mesh and its shading error (``error``: mm's, where known). A pass that would
    end past ``run.deadline`` (90 % into the time limit) less ``tail`` seconds (the first
    takes about ``first_pass`` seconds, a later one as long as the one before) is left out,
    and ``run.notes["fit_passes"]`` says so."""
    moving = [(note, move) for on, note, move in (
        (run.s.fit_base_stiffness > 0, "base_fit", _base_moved),
        (run.s.fit_directions, "direction_fit", _directions_turned)) if on]
    if not moving or run.s.fit_passes < 1:
        return mm, error
    for note, _ in moving:
        run.notes.pop(note, None)
    with run.timer.phase("fit"):
        shell = micromesh_shell_volume(mm, tight_bounds(mm))
    known, cap, last = (error, shell), _SHELL_GROWTH * shell, first_pass
    for n in range(run.s.fit_passes):
        began = time.perf_counter()
        if _ends_past_deadline(run, last + tail):  # this pass would overrun the limit
            run.notes["fit_passes"] = {"done": n, "cut_by_time_limit": True}
            break
        for note, move in moving:
            run.check_stop()
            run.announce(note)
            mm, known = _kept(run, note, mm, move(run, mm, samples), samples, known, cap)
        last = time.perf_counter() - began
    return mm, known[0]


# The rounds that move the base and turn the directions are kept where the shell they leave
# is at most this factor of the one before the first of them.
_SHELL_GROWTH = 1.1


def _base_moved(run: RunState, mm: MicroMesh, samples) -> MicroMesh:
    """One fit round with the base vertices as unknowns, but for ``run.held_in_fit``
    (``core.construct.held``), which stay where they are. On parts thinner than the samples'
    spacing a base vertex can be pulled across to the far side, and its shell with it: a
    vertex whose span (the thickness of its shell, ``core.micro.bounds.reach``) grows past
    ``_SPAN_GROWTH`` times its span before, plus ``_SPAN_FLOOR`` mean base edges, is put back,
    and the displacements are fitted again around it: a few such vertices would otherwise
    make the shell's cap refuse the whole round."""
    with run.timer.phase("fit"):
        moved = fit_rounds(run, mm, samples, run.s.fit_base_stiffness, rounds=1,
                           fixed_base=run.held_in_fit)
        grown = reach(moved) > _SPAN_GROWTH * reach(mm) + _SPAN_FLOOR * run.h
        run.notes.setdefault("base_fit_vertices_put_back", []).append(int(grown.sum()))
        if grown.any():
            vertices = moved.base.vertices.copy()
            vertices[grown] = mm.base.vertices[grown]
            moved = fit_rounds(run, moved.with_base_positions(vertices), samples, rounds=1)
        return moved


_SPAN_GROWTH = 2.0
_SPAN_FLOOR = 0.01


def _directions_turned(run: RunState, mm: MicroMesh, samples) -> MicroMesh:
    """One fit round with the base directions as unknowns too (``core.fit.fit_directions``),
    then one over the displacements (a direction put back leaves its neighbours' values
    off)."""
    with run.timer.phase("fit"):
        turned = fit_directions(mm, samples, run.s.fit_smoothness, run.s.fit_slopes)
        return fit_rounds(run, turned, samples, rounds=1)


def _kept(run: RunState, note: str, mm: MicroMesh, moved: MicroMesh, samples,
          known: tuple, cap: float) -> tuple[MicroMesh, tuple[float, float]]:
    """(``moved`` where it lowers the shading error of ``samples`` and leaves a shell of at
    most ``cap``, else ``mm``; that one's (shading error, shell)). ``known``: mm's (shading
    error, shell), the error None where the caller has not measured it. ``run.notes[note]``
    says what the passes of this round did: whether any was kept and how many, the error and
    shell before the first and after the last."""
    error, shell = known
    with run.timer.phase("fit"):
        if error is None:
            error = float(surface_errors(mm, samples)[1].sum())
        after = float(surface_errors(moved, samples)[1].sum())
        shell_after = micromesh_shell_volume(moved, tight_bounds(moved))
    keep = bool(after < error and shell_after <= cap)
    out, known = (moved, (after, shell_after)) if keep else (mm, (error, shell))
    first = run.notes.get(note, {"kept": False, "passes_kept": 0,
                                 "shading_error_before": error, "shell_before": float(shell)})
    run.notes[note] = {**first, "kept": first["kept"] or keep,
                       "passes_kept": first["passes_kept"] + keep,
                       "shading_error_after": known[0], "shell_after": float(known[1])}
    return out, known


def _exchanged(run: RunState, mm: MicroMesh, samples) -> tuple[MicroMesh, tuple, float | None]:
    """The residual exchange of levels, fitted, kept where it lowers the shading error; the
    micro-mesh kept, the samples that fit it and, where it is the first, its shading error on
    them."""
    with run.timer.phase("residual_lod"):
        dist, normal = surface_errors(mm, samples)
        new = residual_exchange(run, mm.levels, _share(dist) + _share(normal))
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


def _share(error: np.ndarray) -> np.ndarray:
    """Each face's part of the total ``error`` (zeros where there is none): the residual
    exchange weighs the faces' distance and shading errors alike."""
    total = float(error.sum())
    return error / total if total > 0 else np.zeros_like(error)


def fit_rounds(run: RunState, mm: MicroMesh, samples, base_stiffness: float = 0.0,
               rounds: int = 2, fixed_base: np.ndarray | None = None) -> MicroMesh:
    """The least-squares fit with the run's settings (the base vertices held with
    ``base_stiffness``, fixed at 0, ``fixed_base`` fixed); one round suffices from an
    already fitted ``mm``."""
    return fit_micromesh(mm, run.scene.ref, run.s.fit_smoothness, rounds, samples=samples,
                         slopes=run.s.fit_slopes, base_stiffness=base_stiffness,
                         fixed_base=fixed_base)
