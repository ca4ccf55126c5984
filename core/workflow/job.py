"""One construction, bpy-free: a :class:`Job` (world-space meshes and cameras, settings, the
method) in, a world-space :class:`~core.workflow.outcome.Outcome` out.

Runs in the worker thread (and synchronously in background mode and in ``batch.py``): the one
workflow behind the Construct operator and the command line, which each only build the job. Without a base mesh it builds
one first (``core.base``, the settings' ``base_*`` targets). Inside, everything happens in
the unit-sphere frame of the reference (``docs/architecture.md``); the result is mapped back
like the core does (base positions inverted, directions kept, displacements and bounds scaled
by 1/scale).

Two methods: the optimiser (``core.construct.construct``), which also runs "keep face
levels" (the artist's levels fixed, base frozen, displacements baked then optimised), and the
staged baseline (``core.construct.staged_baseline``: uniform or given levels, projection
baking, tight bounds), an explicit choice.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..micro.bounds import micromesh_shell_volume
from ..render.cameras import Cameras
from ..construct import ConstructCancelled, construct, staged_baseline
from ..mesh.trimesh import TriMesh
from .outcome import Outcome
from ..report.make import make_report
from ..settings.fields import ConstructSettings, to_dict


class Cancelled(Exception):
    """The user stopped the construction; nothing was produced."""


@dataclass(eq=False)
class Job:
    """One construction: ``reference`` (world space) and ``settings``; ``base`` (world space;
    None: built from the settings), ``cameras`` (None: the settings' Fibonacci sphere).

    ``method``: "optimize" (core.construct; with ``levels`` (nf,) those are kept fixed and
    only the displacements are optimised) or "projection" (the staged baseline at ``levels``
    or the uniform ``level``, default ``settings.max_level``); "auto" means "optimize". The
    run report (``core.report``) compares the settings with ``preset_name``'s.
    ``input_warnings``: what reading the input found (e.g. triangulated polygons)."""

    reference: TriMesh
    settings: ConstructSettings
    base: TriMesh | None = None
    cameras: Cameras | None = None
    method: str = "optimize"
    levels: np.ndarray | None = None
    level: int | None = None
    preset_name: str = "default"
    input_warnings: list[str] = field(default_factory=list)


def run(job: Job, progress: Callable = lambda p: None,
        should_stop: Callable[[], bool] = lambda: False) -> Outcome:
    """Construct ``job``'s micro-mesh.

    Args:
        job: the inputs (world space) and settings.
        progress: called with each ``core.construct.Progress`` (phase, iteration, total,
            loss, PSNR, seconds left).
        should_stop: polled between steps; True cancels.

    Returns:
        The :class:`Outcome` in world space: the micro-mesh (directions as computed in the
        unit frame, displacements and bounds in world units), its bounds, the metrics
        (``shell_volume`` measured in the unit-sphere frame, the paper's; ``warnings``: the
        job's ``input_warnings``, then how the base's topology differs from the input's),
        the settings as a dict, the history, and the report where the settings ask for one.

    Raises:
        Cancelled: ``should_stop()`` turned true.
        core.construct.ConstructError: inputs the construction cannot take.
    """
    reference, base, settings, method = job.reference, job.base, job.settings, job.method
    levels, level = job.levels, job.level
    t0 = time.perf_counter()
    if method not in ("auto", "optimize", "projection"):
        raise ValueError(f"method must be auto, optimize or projection, not {method!r}")
    try:
        if method == "projection":
            res = _projection(reference, base, settings, progress, should_stop, levels, level)
        else:
            res = construct(reference, base, job.cameras, settings, progress=progress,
                            should_stop=should_stop, levels=levels)
    except ConstructCancelled:
        raise Cancelled("construction cancelled") from None
    if should_stop():
        raise Cancelled("construction cancelled")
    mm = res.micromesh
    metrics = dict(res.metrics or {})
    metrics["warnings"] = list(job.input_warnings) + list(metrics.get("warnings", []))
    if "shell_volume" not in metrics:
        metrics["shell_volume"] = micromesh_shell_volume(res.micromesh_unit, None)
    metrics.update(base_faces=int(mm.base.n_faces), micro_vertices=int(mm.n_vertices),
                   micro_triangles=int(mm.topology.n_triangles),
                   reference_faces=int(reference.n_faces), time_s=time.perf_counter() - t0)
    out = Outcome(mm, res.bounds, metrics, to_dict(settings), dict(res.history or {}),
                  "projection" if method == "projection" else "optimize")
    if settings.compute_metrics:                  # the run report (core.report)
        progress({"phase": "report", "iteration": 0, "total": 1})
        out.report_png, out.report = make_report(res, reference, metrics, job.preset_name)
    return out


def _projection(reference, base, settings, progress, should_stop, levels, level):
    """The staged baseline on ``base`` (or the settings' base) at the given levels."""
    lv = levels if levels is not None else (settings.max_level if level is None else level)
    return staged_baseline(reference, base, lv, settings, evaluate_metrics=settings.compute_metrics,
                           progress=progress, should_stop=should_stop)
