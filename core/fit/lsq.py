"""The fit's rounds: match, assemble, solve (an ICP on the displacements, and on the base
vertices where they may move)."""
from __future__ import annotations

import numpy as np

from ..mesh.trimesh import TriMesh
from ..micro.micromesh import MicroMesh
from .samples import FitError, fit_samples
from .solve import solve_normal_equations
from .system import normal_equations


def fit_displacements(mm: MicroMesh, reference: TriMesh, smoothness: float = 1e-3,
                      iterations: int = 2, density: float = 2.0, samples=None,
                      slopes: float = 0.1) -> np.ndarray:
    """Displacements (n,) of ``mm``'s micro-vertices fitted to ``reference`` (see the package
    docstring), its base kept; ``mm``'s own displacements are the starting point.

    ``density``: reference samples per micro-triangle at least (large reference faces are
    subdivided for it). ``samples``: the output of
    :func:`reference_samples`, when the caller reuses it.
    """
    return fit_micromesh(mm, reference, smoothness, iterations, density, samples,
                         slopes).displacements


def fit_micromesh(mm: MicroMesh, reference: TriMesh, smoothness: float = 1e-3,
                  iterations: int = 2, density: float = 2.0, samples=None, slopes: float = 0.1,
                  base_stiffness: float = 0.0, fixed_base: np.ndarray | None = None
                  ) -> MicroMesh:
    """``mm`` fitted to ``reference``: its displacements and, with ``base_stiffness`` > 0,
    its base vertices too (directions kept). A base vertex moves where that brings the
    micro-surface closer and its triangles flatter against the samples: sideways onto a
    crease, which one displacement per micro-vertex cannot reach; ``base_stiffness`` holds
    it (times the sample weight per base vertex times its squared move); ``fixed_base``
    (nb,) bool: base vertices that stay exactly where they are.
    """
    if smoothness < 0 or slopes < 0 or base_stiffness < 0 or iterations < 1 \
            or not density > 0:
        raise FitError("smoothness, slopes and base_stiffness must be >= 0, iterations >= 1 "
                       "and density > 0")
    if samples is None:
        samples = fit_samples(mm, reference, density)
    n, nb = mm.n_vertices, mm.base.n_vertices
    d = mm.displacements.copy()
    offsets = np.zeros((nb, 3))
    for _ in range(iterations):
        M, b = normal_equations(mm, d, samples, smoothness, slopes, base_stiffness, offsets,
                                fixed=fixed_base)
        if base_stiffness > 0:
            # 300 CG steps, converged or not: as good as a full solve (counter_cad's
            # micro-mesh: 200 to 2000 steps all 33.34 dB; 2000 did not converge).
            x = solve_normal_equations(M, b, np.concatenate([d, np.zeros(3 * nb)]),
                                       maxiter=300, blocks=nb, exact=False)
        else:
            x = solve_normal_equations(M, b, d)
        d = x[:n]
        if base_stiffness > 0:
            offsets = offsets + x[n:].reshape(3, nb).T
    out = mm.with_displacements(np.asarray(d, dtype=np.float64))
    return out.with_base_positions(mm.base.vertices + offsets) if base_stiffness > 0 else out
