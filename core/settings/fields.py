"""Settings of a micro-mesh construction: one flat dataclass, named presets
(``core.settings.presets``), overrides.

Every knob is a plain field so ``--set key=value`` (batch.py, the add-on) maps onto it with
``core.settings.overrides.apply_overrides``. The ablation switches of the paper's tables are fields too
(``reparameterize``, ``progressive``, ``w_sv``, ``w_iso``, ``lod_criterion``, ``n_views``,
``lambda_base`` / ``lambda_micro``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .presets import PRESETS
from .rules import problems


class SettingsError(ValueError):
    """A preset name or an override is not valid."""


@dataclass(frozen=True)
class ConstructSettings:
    """All parameters of :func:`core.construct.construct`.

    Iteration numbers are absolute; ``subdivide_at`` lists the iterations at which one level is
    added (the paper: 50/150/400/800 of 1600). ``freeze_base_at`` starts the last phase that
    tunes displacements only (``-1``: after the last subdivision event).
    """

    preset: str = "default"
    device: str = "auto"             # "cpu", "cuda", "auto"
    seed: int = 0
    threads: int = 0                 # 0: all usable cores (core.runtime.threads.set_threads)

    # schedule
    iterations: int = 400
    subdivide_at: tuple[int, ...] = (25, 75, 150, 250)
    max_level: int = 4               # ℓmax (≤ 5)
    min_level: int = 1               # ℓmin of Algorithms 1 and 2
    freeze_base_at: int = -1
    time_limit_s: float = 0.0        # > 0: compress the schedule to finish within this time
                                     # (the fit and metrics' estimate included)
    progressive: bool = True         # False: subdivide to ℓmax before optimising (ablation)

    # base mesh, built by core.base.build_base when the caller gives none
    base_method: str = "collapse"    # which base builder (core.base.builders) makes a missing base
    base_ratio: float = 1 / 32       # target faces as a fraction of the input's (0: error only)
    base_faces: int = 0              # target face count (> 0: instead of the ratio)
    base_max_error: float = 1e-3     # RMS distance bound / bbox diagonal (0: none)
    base_max_distance: float = 4e-3  # largest distance bound / bbox diagonal: the RMS bound
                                     # tightened until it holds (core.base.build; 0: none)
    base_min_quality: float = 0.4    # floor on 2r/R of new base triangles
    base_refine: float = 8.0         # then edges split where a face holds more than this
                                     # many times the mean face's (furthest reference
                                     # vertex x area; core.base.refine; 0: none)

    # adaptive level of detail and the storage budget (the first of the three that is > 0)
    lod: str = "in_optim"            # "in_optim" (Alg. 1), "post" (Alg. 2), "uniform"
    lod_criterion: str = "visual"    # "visual" or "chamfer" (ablation)
    tau_in: float = 0.1
    tau_post: float = 0.03
    budget_bytes: int = 0            # bytes on disk (the .bin + .bary, core.io.file_size)
    budget_micro_triangles: int = 0  # micro-triangles
    budget_ratio: float = 2.0        # the .bin + .bary micromesh-tools' "microexpansion 2"
                                     # (micro-triangles per input face) writes on the base
                                     # (core.construct.state.budget_cost,
                                     # core.lod.expansion); 0 with the others 0: no budget

    # parameters / optimiser
    reparameterize: bool = True      # False: Laplacian smoothing term instead (ablation)
    laplacian_weight: float = 1.0    # weight of that term
    lambda_base: float = 19.0
    lambda_micro: float = 9.0
    lr_base: float = 3e-4
    lr_disp: float = 1e-3
    betas: tuple[float, float] = (0.9, 0.999)
    grad_clip: float = 1.0           # max gradient norm per parameter tensor (0: off)
    init_new_levels: str = "bake"    # new micro-vertices: "bake" (projection), "interpolate"
                                     # (paper), "rebake" (every micro-vertex, measurement)
    init_bake: bool = True           # start displacements from projection baking
    base_warm_up: bool = True        # at level 0 only the base moves (displacements 0)
    hold_exact_base: bool = True     # base vertices (or their stars) on the reference stay put
                                     # (core.construct.held; ours)
    final_fit: bool = True           # fit the displacements to the reference at the end
                                     # (core.fit, least squares; ours)
    fit_smoothness: float = 1e-3     # weight of |L (|D| d)|² in the fit
    fit_slopes: float = 0.1          # weight of the micro-triangles' tilt against the samples'
    fit_base_stiffness: float = 1e-3  # how firmly the fit holds the base vertices (0: fixed)
    fit_directions: bool = True      # then turn the base directions too, where that helps
                                     # (core.fit.directions; ours)
    fit_passes: int = 5              # the base round and the directions' round, this many
                                     # times (the shell within a tenth over all of them)
    residual_lod: float = 0.15       # after the fit, this fraction of faces may go up a level
                                     # where it still misses the reference, others down, same
                                     # budget, then fit again (0: off; ours)
    fold_bounds: bool = True         # fold the tight bounds into base and directions: the
                                     # result is what a .bary file holds (core.micro.bounds.baked)
    lp_bounds: bool = True           # fold the least-volume bounds first and fit again
                                     # (core.micro.least_volume.lp_bounds; ours): a thinner shell
    polish_steps: int = 0            # then image steps on the values within those bounds
                                     # (core.construct.polish; ours; 0: none; "quality": 40)

    # losses
    w_render: float = 1.0
    w_sv: float = 10.0
    w_range: float = 0.0             # shell range term (ours; core.construct.losses.shell_range_loss)
    w_iso: float = 1.0
    paper_losses: bool = False       # L_sv and L_iso as published: in the unit-sphere frame,
                                     # not divided by h², and L_iso's gradient through the
                                     # optimiser with the others (ours: a tangent step of its own)

    # cameras and images
    n_views: int = 24
    views_per_iter: int = 4
    train_resolution: int = 256
    camera_radius: float = 3.5
    fov_y_deg: float = 35.0
    antialias: bool = True
    shading: str = "flat"            # "flat": facets (how micro-triangles ray-trace without
                                     # shading normals) or "shaded" (interpolated normals)
    lod_resolution: int = 192        # resolution of the per-face error renders for the LOD

    # evaluation
    eval_views: int = 24
    eval_resolution: int = 512
    compute_metrics: bool = True
    geom_error: bool = True

    def validate(self) -> "ConstructSettings":
        """Raise :class:`SettingsError` naming every setting outside its allowed values
        (``core.settings.rules``); return self."""
        bad = problems(self, PRESETS)
        if bad:
            raise SettingsError("; ".join(bad))
        return self

    def budget(self) -> tuple[str, float]:
        """The storage budget as ("bytes" | "micro_triangles" | "expansion", amount), or
        ("", 0): none. "expansion": micro-triangles per input face, which the base turns
        into the bytes micromesh-tools' uniform tessellation would take (``core.lod.expansion``,
        ``core.construct.state.budget_cost``)."""
        if self.budget_bytes > 0:
            return "bytes", float(self.budget_bytes)
        if self.budget_micro_triangles > 0:
            return "micro_triangles", float(self.budget_micro_triangles)
        if self.budget_ratio > 0:
            return "expansion", float(self.budget_ratio)
        return "", 0.0

    @property
    def base_freeze_iteration(self) -> int:
        if self.freeze_base_at >= 0:
            return self.freeze_base_at
        last = max(self.subdivide_at) if self.subdivide_at else 0
        # Leave the displacements-only phase the last fifth of the run at least.
        return max(last, int(0.8 * self.iterations)) if self.progressive else int(0.8 * self.iterations)


def preset(name: str = "default", **overrides) -> ConstructSettings:
    """The named preset (``fast``, ``default``, ``quality``, ``paper``) with field overrides."""
    if name not in PRESETS:
        raise SettingsError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}")
    base = dict(PRESETS[name])
    base.update(overrides)
    try:
        return ConstructSettings(preset=name, **base).validate()
    except TypeError as e:
        raise SettingsError(str(e)) from None


def to_dict(settings: ConstructSettings) -> dict:
    """JSON-friendly dict of the settings."""
    d = dataclasses.asdict(settings)
    return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}
