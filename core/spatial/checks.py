"""Input checks shared by the point queries (:mod:`core.spatial.bake`, :mod:`core.spatial.closest`).

Each raises the caller's own error class (a ``ValueError``), so messages stay specific to the
module the user called.
"""
from __future__ import annotations

import numpy as np


def as_points(a, name: str, error: type[ValueError]) -> np.ndarray:
    """``a`` as a finite float64 (n, 3) array."""
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise error(f"{name} must be (n, 3), got {a.shape}")
    if not np.isfinite(a).all():
        raise error(f"{name} contain NaN or infinity")
    return a


def per_point_distance(value, n: int, error: type[ValueError]) -> np.ndarray:
    """A ``max_distance`` (scalar or (n,)) as an (n,) float64 array of values >= 0 (inf allowed)."""
    d = np.asarray(value, dtype=np.float64)
    if d.ndim == 0:
        d = np.full(n, float(d))
    if d.shape != (n,):
        raise error(f"max_distance must be a scalar or ({n},), got {d.shape}")
    if np.isnan(d).any() or (d < 0).any():
        raise error("max_distance must be non-negative (inf for unlimited)")
    return d
