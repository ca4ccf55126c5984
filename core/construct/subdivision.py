"""A subdivision event of the schedule: measure the per-face errors, choose the next levels
(:mod:`core.construct.choose_levels`) and give the new micro-vertices their displacements.
Micro-vertices that existed before keep their optimised values."""
from __future__ import annotations

import numpy as np

from ..bake import SOURCE_NEAREST, bake_displacements
from ..lod import effective_micro_triangles, relative_gain
from .choose_levels import next_levels
from .params import Parameters
from .scene import face_errors
from .state import RunState


def subdivide(run: RunState, params: Parameters, it: int) -> None:
    """One level up where the LOD and the budget allow; ``run.level`` advances either way."""
    s = run.s
    cur = params.micromesh()
    old = cur.levels.copy()
    errs = face_errors(cur, run.scene, run.lod_cams, s, run.ref_tree) \
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
    nxt, kept = cur.resampled(new)
    if not kept.all():
        # New micro-vertices: projected onto the reference ("bake", ours), or onto the
        # current displaced surface ("interpolate", the paper's rule made exact: each lies on
        # the surface it subdivides); "rebake" projects every micro-vertex onto the
        # reference again (the measurement's alternative). The warm-up left the level-0
        # values at zero, untrained: those are baked too. Where a projection falls back to
        # the nearest point (no ray hit within reach: the spikes of plain baking) the
        # resampled value stays.
        warmed = s.base_warm_up and run.level == 0
        every = s.init_new_levels == "rebake" or (warmed and s.init_new_levels == "bake")
        todo = np.arange(nxt.n_vertices) if every else np.flatnonzero(~kept)
        onto = cur.tessellate().to_trimesh() if s.init_new_levels == "interpolate" and \
            not warmed else run.scene.ref
        br = bake_displacements(nxt.micro_vertex_base_positions()[todo],
                                nxt.micro_vertex_directions()[todo], onto,
                                max_distance=run.bake_distance)
        d = nxt.displacements.copy()
        d[todo] = np.where(br.source == SOURCE_NEAREST, d[todo], br.displacement)
        nxt = nxt.with_displacements(d)
    params.set_micromesh(nxt)
    run.event(iteration=it, level=run.level + 1, subdivided=int((new > old).sum()),
              micro_triangles=effective_micro_triangles(new, run.base))
    run.level += 1
