"""A subdivision event of the schedule: measure the per-face errors, choose the next levels
(:mod:`core.construct.choose_levels`) and give the new micro-vertices their displacements."""
from __future__ import annotations

import numpy as np

from ..bake import SOURCE_NEAREST, bake_displacements
from ..lod import micro_triangle_count, relative_gain
from .choose_levels import next_levels
from .params import Parameters
from .scene import face_errors
from .state import RunState


def subdivide(run: RunState, params: Parameters, it: int) -> None:
    """One level up where the LOD and the budget allow; ``run.level`` advances either way."""
    s = run.s
    cur = params.micromesh()
    old = cur.levels.copy()
    errs = face_errors(cur, run.scene, run.lod_cams, "lod", s, run.ref_tree) \
        if (s.lod == "in_optim" or run.budget > 0) else None
    gains = None
    if errs is not None and run.last_errors is not None:
        gains = relative_gain(run.last_errors, errs)
        run.gains[run.level] = gains
    new = next_levels(run, old, errs, gains)
    if errs is not None:
        run.last_errors = errs
    if np.array_equal(new, old):
        run.event(iteration=it, level=run.level + 1, subdivided=0)
        run.level += 1
        return
    nxt = cur.with_levels(new)
    o = nxt.micro_vertex_base_positions()
    dd = nxt.micro_vertex_directions()
    if s.init_new_levels == "bake":
        # Our addition: project the new micro-vertices onto the reference.
        br = bake_displacements(o, dd, run.scene.ref, max_distance=run.bake_distance)
    else:
        # The paper's interpolation, made exact: intersect each new vertex's line with the
        # current displaced surface, so every new micro-vertex lies on it.
        br = bake_displacements(o, dd, cur.tessellate().to_trimesh(),
                                max_distance=run.bake_distance)
    # Keep the resampled value where the projection fell back to the nearest point
    # (no ray hit within reach): those are the spikes of plain baking.
    nxt = nxt.with_displacements(np.where(br.source == SOURCE_NEAREST,
                                          nxt.displacements, br.displacement))
    params.set_micromesh(nxt)
    run.event(iteration=it, level=run.level + 1, subdivided=int((new > old).sum()),
              micro_triangles=micro_triangle_count(new))
    run.level += 1
