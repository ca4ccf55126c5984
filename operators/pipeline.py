"""One construction, bpy-free: world-space meshes and cameras in, a world-space result out.

Runs in the worker thread (and synchronously in background mode and in ``batch.py``). Inside,
everything happens in the unit-sphere frame of the reference (``docs/architecture.md``); the
result is mapped back like the core does (base positions inverted, directions kept,
displacements and bounds scaled by 1/scale).

Two methods: the optimiser (``core.construct.construct``), which also runs "keep face
levels" (the artist's levels fixed, base frozen, displacements baked then optimised), and the
staged baseline (uniform or given levels, projection baking, tight bounds), an explicit choice.
"""
from __future__ import annotations

import importlib.util
import time
from typing import Callable

import numpy as np

from ..core.cameras import Cameras
from ..core.mesh import TriMesh, unit_sphere_normalization
from ..core.micromesh import MicroMesh
from ..core.settings import ConstructSettings, to_dict
from .writeback import Outcome


class PipelineCancelled(Exception):
    """The user stopped the construction; nothing was produced."""


def has_optimizer() -> bool:
    """True when the optimiser's entry point (``core.construct``) is available."""
    return importlib.util.find_spec(__package__.rsplit(".", 1)[0] + ".core.construct") is not None


def run(reference: TriMesh, base: TriMesh, cameras: Cameras | None, settings: ConstructSettings,
        progress: Callable = lambda p: None, should_stop: Callable[[], bool] = lambda: False,
        levels: np.ndarray | None = None, level: int | None = None,
        method: str = "auto") -> Outcome:
    """Construct a micro-mesh of ``reference`` on ``base`` (both world space).

    ``method``: "optimize" (core.construct; with ``levels`` those are kept fixed and only the
    displacements are optimised), "projection" (the staged baseline at ``levels`` or the
    uniform ``level``, default ``settings.max_level``) or "auto" (optimize when available). Raises :class:`PipelineCancelled` (or the core's
    ``ConstructCancelled``) when ``should_stop()`` turns true. The result follows the core's
    convention: directions as computed in the unit frame, displacements and bounds in world
    units; ``metrics["shell_volume"]`` is measured in the unit-sphere frame (the paper's).
    """
    t0 = time.perf_counter()
    if method == "auto":
        method = "optimize" if has_optimizer() else "projection"
    if method == "optimize":
        from ..core.construct import construct

        res = construct(reference, base, cameras, settings, progress=progress,
                        should_stop=should_stop, levels=levels)
        mm_w, bounds = res.micromesh, res.bounds
        mm_u = res.micromesh_unit
        metrics = dict(res.metrics or {})
        history = dict(res.history or {})
    elif method == "projection":
        norm = unit_sphere_normalization(reference.vertices)
        ref_u = TriMesh(norm.apply(reference.vertices), reference.faces)
        base_u = TriMesh(norm.apply(base.vertices), base.faces)
        mm_u, metrics = _staged(ref_u, base_u, settings, progress, should_stop, levels, level)
        if settings.compute_metrics and has_optimizer():
            from ..core.construct import evaluate

            progress({"phase": "metrics", "iteration": 2, "total": 2, "fraction": 0.97})
            metrics.update(evaluate(mm_u, ref_u, settings))
        inv = 1.0 / norm.scale
        mm_w = MicroMesh(TriMesh(norm.invert(mm_u.base.vertices), mm_u.base.faces),
                         mm_u.directions, mm_u.levels, mm_u.displacements * inv, mm_u.topology)
        bounds = None
        history = {}
    else:
        raise ValueError(f"method must be auto, optimize or projection, not {method!r}")
    if should_stop():
        raise PipelineCancelled("construction cancelled")
    from ..core.bounds import micromesh_shell_volume, tight_bounds

    if bounds is None:
        bounds = tight_bounds(mm_w)
    if "shell_volume" not in metrics and mm_u is not None:
        metrics["shell_volume"] = micromesh_shell_volume(mm_u)
    metrics.update(base_faces=int(mm_w.base.n_faces), micro_vertices=int(mm_w.n_vertices),
                   micro_triangles=int(mm_w.topology.n_triangles),
                   reference_faces=int(reference.n_faces), time_s=time.perf_counter() - t0)
    return Outcome(mm_w, bounds, metrics, to_dict(settings), history, method)


def _staged(ref_u, base_u, settings, progress, should_stop, levels, level):
    """The staged baseline: flat micro-mesh at the levels, projection-baked displacements
    (ray hits within two mean base edge lengths, else the nearest surface point)."""
    from ..core.bake import bake_displacements

    def check():
        if should_stop():
            raise PipelineCancelled("construction cancelled")

    lv = levels if levels is not None else (settings.max_level if level is None else level)
    progress({"phase": "tessellate", "iteration": 0, "total": 2, "fraction": 0.05})
    check()
    mm = MicroMesh.flat(base_u, lv)
    origins = mm.micro_vertex_base_positions()
    dirs = mm.micro_vertex_directions()
    e = base_u.edges
    reach = 2.0 * float(np.linalg.norm(base_u.vertices[e[:, 0]] - base_u.vertices[e[:, 1]], axis=1).mean())
    check()
    progress({"phase": "bake", "iteration": 1, "total": 2, "fraction": 0.3})
    baked = bake_displacements(origins, dirs, ref_u, max_distance=reach)
    check()
    progress({"phase": "bounds", "iteration": 2, "total": 2, "fraction": 0.95})
    metrics = {"bake_fallback": int(baked.n_fallback)}
    return mm.with_displacements(np.asarray(baked.displacement, dtype=np.float64)), metrics
