"""The staged baseline (Maggiordomo et al. 2023 style), the simplest alternative to the
optimiser: the given base at given or uniform levels, area-weighted normals as directions,
projection baking, tight bounds, no optimisation."""
from __future__ import annotations

import numpy as np

from ..bounds import tight_bounds
from ..losses import mean_edge_length
from ..mesh import TriMesh, unit_sphere_normalization
from ..metrics import PhaseTimer
from ..micromesh import MicroMesh
from ..settings import ConstructSettings, preset
from ..threads import set_threads
from .evaluate import evaluate
from .frame import check_inputs, to_caller_frame
from .scene import bake
from .types import ConstructResult


def staged_baseline(reference: TriMesh, base: TriMesh, level,
                    settings: ConstructSettings | None = None,
                    evaluate_metrics: bool = True) -> ConstructResult:
    """``base`` at ``level`` (one int, or one per face), directions the area-weighted normals,
    displacements by projection baking (nearest of the two ray hits within two mean base edge
    lengths, nearest-point fallback), tight bounds."""
    s = (settings or preset("default")).validate()
    check_inputs(reference, base)
    set_threads(s.threads)
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
    metrics = {}
    if evaluate_metrics:
        with timer.phase("metrics"):
            metrics = evaluate(mm, ref_u, s, bounds)
    metrics["time_s"] = timer.times.get("setup", 0) + timer.times["bake"]
    out, b = to_caller_frame(mm, bounds, norm)
    return ConstructResult(out, b, {}, metrics, dict(timer.times), {}, s, norm, mm)
