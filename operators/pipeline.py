"""One construction, bpy-free: world-space meshes and cameras in, a world-space result out.

Runs in the worker thread (and synchronously in background mode and in ``batch.py``): the one
workflow behind the Construct operator and the command line. Without a base mesh it builds
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
from typing import Callable

import numpy as np

from ..core.bounds import micromesh_shell_volume
from ..core.cameras import Cameras
from ..core.construct import ConstructCancelled, construct, staged_baseline
from ..core.mesh import TriMesh
from ..core.settings import ConstructSettings, to_dict
from ..core.outcome import Outcome
from ..core.report import make_report


class PipelineCancelled(Exception):
    """The user stopped the construction; nothing was produced."""


def run(reference: TriMesh, base: TriMesh | None, cameras: Cameras | None,
        settings: ConstructSettings, progress: Callable = lambda p: None,
        should_stop: Callable[[], bool] = lambda: False, levels: np.ndarray | None = None,
        level: int | None = None, method: str = "optimize",
        preset_name: str = "default", input_warnings: list[str] = ()) -> Outcome:
    """Construct a micro-mesh of ``reference`` on ``base`` (both world space; ``base`` None:
    build it from the settings).

    ``method``: "optimize" (core.construct; with ``levels`` those are kept fixed and only the
    displacements are optimised) or "projection" (the staged baseline at ``levels`` or the
    uniform ``level``, default ``settings.max_level``); "auto" means "optimize". The run
    report (``core.report``) compares the settings with ``preset_name``'s. Raises
    :class:`PipelineCancelled` when ``should_stop()`` turns true. The result follows the
    core's convention: directions as computed in the unit frame, displacements and bounds in
    world units; ``metrics["shell_volume"]`` is measured in the unit-sphere frame (the
    paper's); ``metrics["warnings"]`` says how the base's topology differs from the input's,
    after ``input_warnings`` (what reading the input found, e.g. triangulated polygons).
    """
    t0 = time.perf_counter()
    if method not in ("auto", "optimize", "projection"):
        raise ValueError(f"method must be auto, optimize or projection, not {method!r}")
    try:
        if method == "projection":
            res = _projection(reference, base, settings, progress, should_stop, levels, level)
        else:
            res = construct(reference, base, cameras, settings, progress=progress,
                            should_stop=should_stop, levels=levels)
    except ConstructCancelled:
        raise PipelineCancelled("construction cancelled") from None
    if should_stop():
        raise PipelineCancelled("construction cancelled")
    mm = res.micromesh
    metrics = dict(res.metrics or {})
    metrics["warnings"] = list(input_warnings) + list(metrics.get("warnings", []))
    if "shell_volume" not in metrics:
        metrics["shell_volume"] = micromesh_shell_volume(res.micromesh_unit, None)
    metrics.update(base_faces=int(mm.base.n_faces), micro_vertices=int(mm.n_vertices),
                   micro_triangles=int(mm.topology.n_triangles),
                   reference_faces=int(reference.n_faces), time_s=time.perf_counter() - t0)
    out = Outcome(mm, res.bounds, metrics, to_dict(settings), dict(res.history or {}),
                  "projection" if method == "projection" else "optimize")
    if settings.compute_metrics:                  # the run report (core.report)
        progress({"phase": "report", "iteration": 0, "total": 1})
        out.report_png, out.report = make_report(res, reference, metrics, preset_name)
    return out


def _projection(reference, base, settings, progress, should_stop, levels, level):
    """The staged baseline on ``base`` (or the settings' base) at the given levels."""
    lv = levels if levels is not None else (settings.max_level if level is None else level)
    return staged_baseline(reference, base, lv, settings, evaluate_metrics=settings.compute_metrics,
                           progress=progress, should_stop=should_stop)
