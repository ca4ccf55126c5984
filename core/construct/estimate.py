"""Time and peak memory of a construction, estimated from the input's face count and the
settings before any heavy work, and the refusal of a run that will not fit in memory.

The model is linear in the work each phase does (faces decimated, micro-triangles rendered
per iteration and view pixel, micro-triangles fitted, faces rendered for the metrics); its
coefficients were fitted to five `default` constructions of ``bench/construct_bench.py``
(60k-100k faces) on the developers' 2-core x86-64 machine, the memory's refitted to runs of
up to 2.15M micro-triangles; every run's metrics keep the
estimate beside the measured peak, and ``bench/scale_bench.py`` prints both for larger inputs.
Times are for that machine; memory is the process's peak resident size.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..settings import ConstructSettings
from .types import ConstructError

_MB = 2 ** 20

# Seconds (2 cores): per input face for the base builder and the metrics; per micro-triangle
# and per view pixel of one iteration; per micro-triangle for the fit; fixed start-up.
_T_FIXED = 5.0
_T_BASE_PER_FACE = 1.0e-4
_T_ITER_FIXED = 0.02
_T_ITER_PER_MICRO = 1.56e-6
_T_ITER_PER_PIXEL = 9.0e-8
_T_FIT_PER_MICRO = 1.7e-4
_T_METRICS_PER_FACE = 3.5e-5
# Bytes: the interpreter, the libraries and what does not grow with the input; per
# micro-triangle (the micro-mesh, the optimiser's state, the fit's samples, matches and normal
# equations: the peak is the fit's); per cached image pixel; per input face (the reference and
# its topology: small beside the rest). Refitted to the measured peaks of 69k-2.15M
# micro-triangle runs (docs/results.md: 1.4-2.0 GB at 140k-200k, 7.1 GB at 2.15M), at or
# within 3 % under each: the first fit (6500 per micro-triangle, from 60k-100k-face inputs
# only) had doubled the largest.
_M_FIXED = 1100 * _MB
_M_PER_FACE = 0
_M_PER_MICRO = 3000
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


def micro_triangles(reference_faces: int, s: ConstructSettings) -> int:
    """The micro-triangles the budget allows (without a budget: four per face per level)."""
    kind, amount = s.budget(reference_faces)
    if kind == "micro_triangles":
        return int(amount)
    if kind == "bytes":
        return int(amount / 2.0)     # about 2 bytes per micro-triangle with its base share
    return int(reference_faces * s.base_ratio * 4 ** s.max_level)


def estimate(reference_faces: int, s: ConstructSettings) -> Estimate:
    """Time and peak memory of constructing a micro-mesh of a ``reference_faces`` input."""
    m = micro_triangles(reference_faces, s)
    train_pixels = s.views_per_iter * s.train_resolution ** 2
    # Coarse to fine: over the schedule the micro-mesh holds about half its final triangles.
    per_iter = _T_ITER_FIXED + _T_ITER_PER_MICRO * 0.5 * m + _T_ITER_PER_PIXEL * train_pixels
    phases = {"base": _T_BASE_PER_FACE * reference_faces,
              "optimize": s.iterations * per_iter,
              "fit": _T_FIT_PER_MICRO * m if s.final_fit else 0.0,
              "metrics": _T_METRICS_PER_FACE * reference_faces if s.compute_metrics else 0.0}
    seconds = _T_FIXED + sum(phases.values())
    if s.time_limit_s > 0:
        seconds = min(seconds, s.time_limit_s + phases["fit"] + phases["metrics"] + _T_FIXED)
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
