"""The start of a run: its state in the reference's unit frame (scene, cameras, the mean
base edge) and the first values of the micro-mesh."""
from __future__ import annotations

import numpy as np

from ..mesh.normalization import unit_sphere_normalization
from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from ..settings.fields import ConstructSettings
from .frame import unit_cameras
from .losses import mean_edge_length
from .scene import Scene, bake
from .state import RunState


def start_run(reference: TriMesh, base: TriMesh, cameras, s: ConstructSettings, device,
              should_stop=None, fixed: np.ndarray | None = None) -> RunState:
    """The run state of ``reference`` and ``base`` (caller's frame) in the reference's unit
    frame, with ``cameras`` (caller's frame, or None: the settings' Fibonacci views) and the
    artist's ``fixed`` levels (or None)."""
    norm = unit_sphere_normalization(reference.vertices)
    ref_u = TriMesh(norm.apply(reference.vertices), reference.faces)
    base_u = TriMesh(norm.apply(base.vertices), base.faces)
    cams = unit_cameras(cameras, norm, s, s.train_resolution)
    run = RunState(s, device, norm, base_u, reference.n_faces,
                   Scene(ref_u, cams, device, s.antialias, s.shading),
                   cams.at_resolution(s.lod_resolution), should_stop or (lambda: False),
                   fixed=fixed, h=mean_edge_length(base_u.vertices, base_u.faces))
    if s.lod_criterion == "chamfer":
        from scipy.spatial import cKDTree
        run.ref_tree = cKDTree(ref_u.vertices)
    return run


def initial_micromesh(run: RunState) -> MicroMesh:
    """Projection-baked displacements at the start level (the fixed levels, level 0 of the
    progressive schedule, or the finest uniform level within the budget)."""
    s, base = run.s, run.base
    if run.fixed is not None:
        # Fixed levels: always start from projection baking (the "re-bake" the artist
        # asked for), then refine the displacements only.
        mm = MicroMesh.flat(base, run.fixed)
        run.level = int(run.fixed.max())
        return mm.with_displacements(bake(mm, run.scene.ref, run.bake_distance))
    start = 0 if s.progressive else s.max_level
    # no progressive schedule: the finest uniform level within the budget
    while (run.cost is not None and start > 0
           and run.cost(np.full(base.n_faces, start)) > run.budget):
        start -= 1
    run.level = start
    mm = MicroMesh.flat(base, np.full(base.n_faces, start))
    if not s.init_bake or (start == 0 and s.base_warm_up):
        return mm                # zero displacements: the warm-up moves the base alone
    return mm.with_displacements(bake(mm, run.scene.ref, run.bake_distance))
