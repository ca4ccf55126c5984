"""The fit's rounds: match, assemble, solve (an ICP on the displacements)."""
from __future__ import annotations

import numpy as np

from ..mesh import TriMesh
from ..micromesh import MicroMesh
from .samples import FitError, fit_samples
from .solve import solve_normal_equations
from .system import normal_equations


def fit_displacements(mm: MicroMesh, reference: TriMesh, smoothness: float = 1e-3,
                      iterations: int = 2, density: float = 2.0, samples=None,
                      slopes: float = 0.1) -> np.ndarray:
    """Displacements (n,) of ``mm``'s micro-vertices fitted to ``reference`` (see the module
    docstring); ``mm``'s own displacements are the starting point.

    ``density``: reference samples per micro-triangle at least (large reference faces are
    subdivided for it). ``samples``: the output of
    :func:`reference_samples`, when the caller reuses it.
    """
    if smoothness < 0 or slopes < 0 or iterations < 1 or not density > 0:
        raise FitError("smoothness and slopes must be >= 0, iterations >= 1 and density > 0")
    if samples is None:
        samples = fit_samples(mm, reference, density)
    d = mm.displacements.copy()
    for _ in range(iterations):
        M, b = normal_equations(mm, d, samples, smoothness, slopes)
        d = solve_normal_equations(M, b, d)
    return np.asarray(d, dtype=np.float64)
