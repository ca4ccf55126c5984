"""Micro-mesh construction: :func:`construct` (the optimiser, method §2–§5),
:func:`staged_baseline` (projection baking, no optimisation) and :func:`evaluate` (§7).

Modules, in the order a construction uses them: ``run`` (the entry point, its stages in
order), ``kernels`` (a cold cache's kernels compiled meanwhile), ``frame`` (inputs into the
unit-sphere frame and back), ``start`` (the run's state and first values), ``scene``
(reference images, per-face errors, baking), ``state`` (the explicit run state), ``params``
(the optimised parameters and their geometry), ``schedule``, ``step`` (one iteration and the
loop), ``choose_levels`` (subdivision events and LOD), ``fitting``, ``finalise``, ``polish``,
``evaluate``; ``baseline`` (the staged method); ``warm`` (the warm-up construction).
"""
from ..settings.fields import ConstructSettings, preset, to_dict
from .baseline import staged_baseline
from .evaluate import evaluate
from .params import torch_vertex_normals
from .run import construct
from .types import ConstructCancelled, ConstructError, ConstructResult, Progress

__all__ = ["ConstructCancelled", "ConstructError", "ConstructResult", "ConstructSettings",
           "Progress", "construct", "evaluate", "preset", "staged_baseline", "to_dict",
           "torch_vertex_normals"]
