"""The explicit state of one construction: what every phase reads and updates."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..render.cameras import Cameras
from ..io.file_size import micromesh_file_bytes
from ..lod import effective_micro_triangles
from ..lod.expansion import expansion_bytes, nominal_expansion_bytes
from ..mesh.trimesh import TriMesh
from ..mesh.normalization import Normalization
from ..micro.metrics import PhaseTimer
from ..settings.fields import ConstructSettings
from .scene import Scene
from .types import ConstructCancelled, Progress


# The phases after the optimiser, in order (what :meth:`RunState.announce` counts).
FINISH_PHASES = ("fit", "residual_lod", "base_fit", "direction_fit", "bounds", "polish", "metrics")


# The estimate of micromesh-tools' bytes is within 0.2 % of its files on its own base, but ours
# differs from it and each face's level rounds differently (igea: 1.001 of its bytes on disk
# at the full estimate): the default budget is this share of the estimate.
ESTIMATE_MARGIN = 0.995


def budget_cost(s: ConstructSettings, base: TriMesh, reference_faces: int):
    """(cost(levels), budget, its unit: "bytes", "disk_bytes" or "micro_triangles") of the
    LOD budget, or (None, 0, ""). Micro-triangles are counted as the result has them (after
    the crack-free edge decimation), as the metrics report them; bytes as our files take them
    on disk (``.bin`` + ``.bary``, ``core.io.file_size``). A budget per input face is the
    ``.bin`` + ``.bary`` micromesh-tools' files take for its uniform tessellation at that
    microexpansion on this base, or on the base its decimation aims at where that is more
    (``core.lod.expansion``): a level costs more bytes per micro-triangle the lower it is, so
    adaptive levels within its micro-triangle count would take more storage than it does.
    That estimate is spent to :data:`ESTIMATE_MARGIN` of it: on another base than micromesh-tools'
    own each face's level rounds differently."""
    kind, amount = s.budget()
    nv = base.n_vertices
    if kind in ("bytes", "expansion"):
        def cost(lv):
            return micromesh_file_bytes(lv, nv)["total"]
        if kind == "bytes":
            return cost, amount, kind
        budget = max(expansion_bytes(base, reference_faces, amount),
                     nominal_expansion_bytes(reference_faces, amount))
        return cost, float(math.floor(ESTIMATE_MARGIN * budget)), "disk_bytes"
    if kind == "micro_triangles":
        return (lambda lv: effective_micro_triangles(lv, base)), amount, kind
    return None, 0.0, ""


@dataclass
class RunState:
    """Settings, frame, scene and bookkeeping of a construction in progress.

    ``level``: the level the schedule has reached; ``gains``: per level, the per-face
    relative gain that level brought; ``last_errors``: the per-face image errors measured at
    the last subdivision; ``fixed``: the artist's levels (then no schedule, no LOD);
    ``notes``: what the run decided on the way (e.g. ``residual_lod``), for the metrics;
    ``progress`` and ``finish_estimate_s`` (the estimate's seconds for the fit, polishing and
    the metrics) serve :meth:`announce`; ``deadline``: ``Schedule.deadline``, where the fit's
    later passes, the bounds' later tries and polishing stop short (the metrics come after).
    """

    s: ConstructSettings
    device: object
    norm: Normalization
    base: TriMesh                      # unit frame, as given
    reference_faces: int
    scene: Scene
    lod_cams: Cameras
    should_stop: Callable[[], bool]
    fixed: np.ndarray | None = None
    held: np.ndarray | None = None     # base vertices the optimiser never moves and
    held_in_fit: np.ndarray | None = None  # those the fit's base round fixes (construct.held)
    ref_tree: object = None
    h: float = 1.0                     # the base's initial mean edge length (unit frame)
    level: int = 0
    timer: PhaseTimer = field(default_factory=PhaseTimer)
    history: dict = field(default_factory=lambda: {"iteration": [], "loss": [], "render": [],
                                                   "psnr": [], "events": []})
    gains: dict = field(default_factory=dict)
    last_errors: np.ndarray | None = None
    notes: dict = field(default_factory=dict)
    progress: Callable[[Progress], None] | None = None
    finish_estimate_s: float = 0.0
    deadline: float = math.inf         # perf_counter(): optional later work ends before it
    _finish_start: float | None = None

    def __post_init__(self) -> None:
        self.cost, self.budget, unit = budget_cost(self.s, self.base, self.reference_faces)
        if self.cost is not None:
            self.notes["budget"] = {unit: int(self.budget)}

    @property
    def bake_distance(self) -> float:
        """How far projection baking looks along a direction: two mean base edges."""
        return 2.0 * self.h

    def check_stop(self) -> None:
        if self.should_stop():
            raise ConstructCancelled("construction cancelled")

    def announce(self, phase: str) -> None:
        """Progress of the phases after the optimiser, one report as each of
        ``FINISH_PHASES`` begins (its place among them as the iteration), with the time left:
        the estimate for them less the time they have taken so far (unknown, NaN, once they
        have taken longer)."""
        if self.progress is None:
            return
        now = time.perf_counter()
        if self._finish_start is None:
            self._finish_start = now
        eta = self.finish_estimate_s - (now - self._finish_start)
        eta = eta if eta > 0 else float("nan")
        self.progress(Progress(phase, FINISH_PHASES.index(phase) + 1, len(FINISH_PHASES), 0.0,
                               float("nan"), eta))

    def event(self, **entry) -> None:
        self.history["events"].append(entry)
