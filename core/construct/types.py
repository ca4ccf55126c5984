"""What a construction reports and returns: progress, the result, its errors."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..micro.bounds import DirectionBounds
from ..mesh.normalization import Normalization
from ..micro.micromesh import MicroMesh
from ..settings.fields import ConstructSettings


class ConstructError(ValueError):
    """The inputs of a construction cannot be used."""


class ConstructCancelled(RuntimeError):
    """Raised when ``should_stop()`` returned True; no partial result exists."""


@dataclass
class Progress:
    """Reported to the progress callback once per iteration (and at phase changes)."""

    phase: str
    iteration: int
    total_iterations: int
    loss: float
    psnr: float
    eta_s: float


@dataclass
class ConstructResult:
    """A finished construction, in the caller's frame.

    ``bounds`` are the tight per-vertex direction bounds (caller's units); ``gains`` the per-face
    subdivision gains per level they were measured at; ``metrics`` see
    :func:`core.construct.evaluate`; ``timings`` seconds per phase; ``history`` per-iteration
    lists (iteration, loss, render, psnr, level events).
    """

    micromesh: MicroMesh
    bounds: DirectionBounds
    gains: dict[int, np.ndarray]
    metrics: dict
    timings: dict[str, float]
    history: dict[str, list]
    settings: ConstructSettings
    normalization: Normalization
    micromesh_unit: MicroMesh = field(repr=False, default=None)  # same result, unit-sphere frame
