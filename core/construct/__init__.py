"""Micro-mesh construction: :func:`construct` (the optimiser, method §2–§5),
:func:`staged_baseline` (projection baking, no optimisation) and :func:`evaluate` (§7).

Modules, in the order a construction uses them: ``frame`` (inputs into the unit-sphere
frame and back), ``scene`` (reference images, per-face errors, baking), ``state`` (the
explicit run state), ``params`` (the optimised parameters and their geometry), ``schedule``,
``step`` (one iteration), ``subdivision`` and ``choose_levels`` (LOD), ``finalise``,
``evaluate``; ``baseline``; ``run`` holds the loop.
"""
from ..settings import ConstructSettings, preset, to_dict
from .baseline import staged_baseline
from .evaluate import evaluate
from .params import torch_vertex_normals
from .run import construct
from .types import ConstructCancelled, ConstructError, ConstructResult, Progress

__all__ = ["ConstructCancelled", "ConstructError", "ConstructResult", "ConstructSettings",
           "Progress", "construct", "evaluate", "preset", "staged_baseline", "to_dict",
           "torch_vertex_normals"]
