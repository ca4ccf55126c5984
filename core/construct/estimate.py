"""Time and peak memory of a construction, estimated from the input's face count and the
settings before any heavy work, and the refusal of a run that will not fit in memory.

The model is linear in the work each phase does (faces decimated and read, micro-triangles
rendered per iteration and view pixel, micro-triangles fitted, faces rendered for the
metrics); its time coefficients were fitted to `default` constructions of 269k and 1.07M
faces on the developers' 2-core machine (docs/results.md, eleventh session; the fit's again
in the fifteenth, with the direction round) and are divided by this machine's speed
relative to that one (``core.runtime.speed``, a probe of a few tens of milliseconds); the
memory's were fitted to runs of up to 2.15M micro-triangles. Every run's
metrics keep the estimate beside the measurement, and ``bench/scale_bench.py`` prints both.
Memory is the process's peak resident size.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..settings.fields import ConstructSettings
from .schedule import END_SHARE
from .types import ConstructError

_MB = 2 ** 20

# Seconds on the estimate's machine (speed 1): per input face for the base builder, for the
# rest of the work on the input (reading, orientation, the scene, the files) and for the
# metrics; per micro-triangle and per view pixel of one iteration; per micro-triangle for the
# fit (with the residual exchange and the bounds); fixed start-up with a warm kernel cache.
_T_FIXED = 3.0
_T_BASE_PER_FACE = 2.6e-5
_T_INPUT_PER_FACE = 1.8e-5
_T_ITER_FIXED = 0.005
_T_ITER_PER_MICRO = 9.0e-7
_T_ITER_PER_PIXEL = 1.6e-8
_T_FIT_PER_MICRO = 5.8e-5
_T_METRICS_PER_FACE = 1.05e-5
# Bytes: the interpreter, the libraries and what does not grow with the input; per
# micro-triangle (the micro-mesh, the optimiser's state, the fit's samples, matches and normal
# equations: the peak is the fit's); per cached image pixel; per input face (the reference and
# its topology: small beside the rest). Refitted when the fit came to match its samples in
# chunks (docs/results.md, eleventh session: 4.5 GB at 2.15M micro-triangles, 7.3 GB at
# 4.3M; 1.0 GB at 167k, which it overestimates by half): the large ones within 4 % above.
_M_FIXED = 1100 * _MB
_M_PER_FACE = 0
_M_PER_MICRO = 1550
_M_PER_PIXEL = 40

@dataclass
class Estimate:
    """Estimated wall seconds (``phases``: seconds per phase) and peak memory in bytes."""
    seconds: float
    peak_bytes: float
    micro_triangles: int
    phases: dict = field(default_factory=dict)

    def text(self) -> str:
        return (f"about {_duration(self.seconds)} and {self.peak_bytes / 2 ** 30:.1f} GB of "
                f"memory for {self.micro_triangles:,} micro-triangles")


# The share of the fit's estimate that runs whatever the deadline (``fitting.fitted``: the
# first fit, then the bounds): 0.42 at 2M faces, 0.48-0.55 at 1M (nineteenth session).
_FIT_LEAST_SHARE = 0.5

# A budget per input face gives a count that depends on the base (``core.lod.expansion``):
# 0.99-1.19 times the nominal one on our bases of the shared meshes, 1.06 on average.
_EXPANSION_ROUNDING = 1.1


def micro_triangles(reference_faces: int, s: ConstructSettings) -> int:
    """The micro-triangles the budget allows (without a budget: four per face per level)."""
    kind, amount = s.budget()
    if kind == "expansion":
        return int(round(amount * reference_faces * _EXPANSION_ROUNDING))
    if kind == "micro_triangles":
        return int(amount)
    if kind == "bytes":
        return int(amount / 2.0)     # about 2 bytes per micro-triangle with its base share
    return int(reference_faces * s.base_ratio * 4 ** s.max_level)


def estimate(reference_faces: int, s: ConstructSettings, speed: float | None = None
             ) -> Estimate:
    """Time and peak memory of constructing a micro-mesh of a ``reference_faces`` input on a
    machine of ``speed`` (default: this one's, :func:`core.runtime.speed.machine_speed`)."""
    if speed is None:
        from ..runtime.speed import machine_speed

        speed = machine_speed()
    m = micro_triangles(reference_faces, s)
    train_pixels = s.views_per_iter * s.train_resolution ** 2
    # Coarse to fine: over the schedule the micro-mesh holds about half its final triangles.
    per_iter = _T_ITER_FIXED + _T_ITER_PER_MICRO * 0.5 * m + _T_ITER_PER_PIXEL * train_pixels
    phases = {"input": _T_INPUT_PER_FACE * reference_faces,
              "base": _T_BASE_PER_FACE * reference_faces,
              "optimize": s.iterations * per_iter,
              "fit": _T_FIT_PER_MICRO * m if s.final_fit else 0.0,
              # polishing: full micro-meshes at the metrics' resolution (until the deadline)
              "polish": s.polish_steps * (_T_ITER_FIXED + _T_ITER_PER_MICRO * m +
                                          _T_ITER_PER_PIXEL * s.views_per_iter *
                                          s.eval_resolution ** 2),
              "metrics": _T_METRICS_PER_FACE * reference_faces if s.compute_metrics else 0.0}
    phases = {k: v / speed for k, v in phases.items()}
    seconds = _T_FIXED / speed + sum(phases.values())
    if s.time_limit_s > 0:
        # The limit holds from the base building to the metrics (``Schedule``: the loop ends
        # where the rest's estimate leaves 90 % of it), but the loop always subdivides (about
        # 10 iterations each) and the fit's first round and the bounds always run (the
        # rest of the fit's estimate only before the deadline).
        least = phases["base"] + _FIT_LEAST_SHARE * phases["fit"] + phases["metrics"] + min(
            phases["optimize"], 10 * len(s.subdivide_at) * per_iter / speed)
        seconds = min(seconds, _T_FIXED / speed + phases["input"] +
                      max(END_SHARE * s.time_limit_s, least))
    images = s.n_views * s.train_resolution ** 2 + s.eval_views * s.eval_resolution ** 2
    peak = _M_FIXED + _M_PER_FACE * reference_faces + _M_PER_MICRO * m + _M_PER_PIXEL * images
    return Estimate(seconds, float(peak), m, phases)


def check_fits(guess: Estimate, available_bytes: float | None) -> None:
    """Refuse, with the estimate and what to change, a run that will not fit in memory."""
    if available_bytes is None or guess.peak_bytes <= available_bytes:
        return
    half = max(1, guess.micro_triangles // 2)
    raise ConstructError(
        f"this construction needs {guess.text()}, but only "
        f"{available_bytes / 2 ** 30:.1f} GB are available: set a smaller budget (e.g. "
        f"budget_micro_triangles={half}, or --budget {half} in batch.py), decimate the input "
        "first, or close other programs")


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"
