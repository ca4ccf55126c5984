"""The staged baseline (Maggiordomo et al. 2023 style), the simplest alternative to the
optimiser: the given base at given or uniform levels, ``direction_normals`` as directions,
projection baking, tight bounds, no optimisation."""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..micro.bounds import baked, tight_bounds, unit_bounds
from .losses import mean_edge_length
from ..mesh.trimesh import TriMesh
from ..mesh.normalization import unit_sphere_normalization
from ..micro.metrics import PhaseTimer
from ..micro.micromesh import MicroMesh
from ..settings.fields import ConstructSettings, preset
from ..runtime.threads import set_threads
from .evaluate import evaluate
from .frame import check_inputs, check_reference, oriented, prepare_base, to_caller_frame
from .scene import bake
from .types import ConstructResult, Progress


def staged_baseline(reference: TriMesh, base: TriMesh | None, level,
                    settings: ConstructSettings | None = None,
                    evaluate_metrics: bool = True, progress: Callable | None = None,
                    should_stop: Callable[[], bool] | None = None) -> ConstructResult:
    """``base`` at ``level`` (one int, or one per face), directions ``direction_normals``,
    displacements by projection baking (nearest of the two ray hits within two mean base edge
    lengths, nearest-point fallback), tight bounds folded in (``core.micro.bounds.baked``).
    ``base`` None: the settings' base is built first, as :func:`core.construct.construct`
    does (``metrics["base"]``); ``metrics["warnings"]`` as there. ``progress``/``should_stop`` serve the base building."""
    s = (settings or preset("default")).validate()
    if base is None:
        check_reference(reference)
    else:
        check_inputs(reference, base)
    set_threads(s.threads)
    reference, warnings = oriented(reference)
    base, base_report, base_warnings = prepare_base(reference, base, s, progress, should_stop)
    warnings += base_warnings
    if progress is not None:
        progress(Progress("bake", 1, 2, 0.0, float("nan"), 0.0))
    timer = PhaseTimer()
    with timer.phase("setup"):
        norm = unit_sphere_normalization(reference.vertices)
        ref_u = TriMesh(norm.apply(reference.vertices), reference.faces)
        base_u = TriMesh(norm.apply(base.vertices), base.faces)
        h = mean_edge_length(base_u.vertices, base_u.faces)
    with timer.phase("bake"):
        levels = np.broadcast_to(np.asarray(level, dtype=np.int64), (base_u.n_faces,))
        mm = MicroMesh.flat(base_u, levels)
        mm = mm.with_displacements(bake(mm, ref_u, 2.0 * h))
        bounds = tight_bounds(mm)
        if s.fold_bounds:
            mm, bounds = baked(mm, bounds), unit_bounds(mm.base.n_vertices)
    metrics = {}
    if evaluate_metrics:
        with timer.phase("metrics"):
            metrics = evaluate(mm, ref_u, s, bounds)
    metrics["time_s"] = timer.times.get("setup", 0) + timer.times["bake"]
    metrics["warnings"] = warnings
    if base_report is not None:
        metrics["base"] = base_report
    out, b = to_caller_frame(mm, bounds, norm)
    return ConstructResult(out, b, {}, metrics, dict(timer.times), {}, s, norm, mm)
