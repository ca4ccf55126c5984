"""What a construction reads from the scene and writes back, for the Construct operator and
``batch.py`` alike: :func:`prepare` reads source, base, cameras and settings in the main thread
(the worker then runs its :class:`core.workflow.Job`); :func:`finish` puts the result in."""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import bpy
import numpy as np

from ..core import workflow
from ..core.workflow.outcome import Outcome
from . import base_ops, bl_mesh, cameras_io, warmup, writeback
from .scene_settings import scene_settings


@dataclass
class Prepared:
    """Everything the worker needs, read from bpy in the main thread."""

    source: bpy.types.Object
    base_obj: bpy.types.Object | None
    work: object  # callable(progress, should_stop) -> core.workflow.outcome.Outcome


def prepare(context, method: str = "auto") -> Prepared:
    """Read source, base, cameras and settings; raises ValueError with a user message."""
    s = context.scene.micromesh
    src = base_ops.source_object(context)
    if src is None:
        raise ValueError("no source: select a mesh object or set the source")
    base_obj = base_ops.base_object(context)
    notes: list[str] = []
    reference = bl_mesh.mesh_to_arrays(src, notes=notes)
    base, tri_poly = None, None         # no base object: the worker builds one (core.base)
    if base_obj is not None:
        base, tri_poly = base_ops.base_arrays(base_obj)
    levels = None
    if s.keep_levels:
        if base_obj is None or tri_poly is None:
            raise ValueError("Keep Face Levels needs a base mesh object")
        levels = writeback.base_levels(base_obj, tri_poly)
        if levels is None:
            raise ValueError(f"base '{base_obj.name}' has no micromesh_level face attribute")
    settings = scene_settings(context.scene)
    cams = None
    if s.use_scene_cameras and s.camera_collection is not None:
        cams = cameras_io.collection_cameras(s.camera_collection, settings.train_resolution)
        if cams is None:
            notes.append(f"the camera collection '{s.camera_collection.name}' holds no "
                         f"cameras: {settings.n_views} cameras around the object were used")
    job = workflow.Job(reference, settings, base, cams, method, levels, s.level,
                       str(s.preset).lower(), notes)
    return Prepared(src, base_obj, partial(_work, job))


def _work(job: workflow.Job, progress, should_stop) -> Outcome:
    warmup.wait(progress, should_stop)     # a first run: the kernels are being compiled
    return workflow.run(job, progress, should_stop)


def finish(context, source, base_obj, outcome: Outcome,
           base_uv: np.ndarray | None = None) -> bpy.types.Object:
    """A finished construction into the scene (the panel and ``batch.py``): the base object
    (linked as ``<source>_base`` when the worker built it, with ``base_uv`` at its corners
    where given), the result, the panel's source and base; returns the result object."""
    if base_obj is None:
        base = outcome.micromesh.base
        base_obj = base_ops.link_base(context, source, base.vertices, base.faces, base_uv)
    obj = writeback.write_result(context, source, base_obj, outcome)
    s = context.scene.micromesh
    s.source, s.base = source, base_obj
    return obj
