"""The field's default storage: micro-triangles "per input face" counted as micromesh-tools
counts its microexpansion.

``tessellate -mode uniform -microexpansion e`` (NVlabs/micromesh-tools, the staged tool's
default is e = 2) aims at e times the input's faces with one global level
L = (log2 e + log2(input faces / base faces)) / 2, gives each base face the nearest whole
level to L + log4(its area / the mean area) (0 at least), and then raises levels until
neighbours differ by at most one. Rounding per face and raising make more micro-triangles
than e × input faces: 2.0-2.47 times the input's faces at e = 2 on the shared meshes
(``docs/results.md``). A budget of e "per input face" is the storage those levels take on
the base at hand, by micromesh-tools' own formula (``core.construct.state.budget_cost``), so
that the default spends what the field's default spends on the same base; adaptive LOD then
places it by visual gain.
"""
from __future__ import annotations

import numpy as np

from ..mesh import TriMesh
from ..mesh_levels import raised_to_balance


def expansion_levels(base: TriMesh, reference_faces: int, expansion: float) -> np.ndarray:
    """(F,) levels of the uniform tessellation of ``base`` at ``expansion`` micro-triangles
    per reference face, balanced (±1 across edges) by raising."""
    if base.n_faces == 0 or reference_faces <= 0 or expansion <= 0:
        return np.zeros(base.n_faces, dtype=np.int64)
    area = np.asarray(base.face_areas, dtype=np.float64)
    mean = float(area.mean())
    if not mean > 0.0:
        return np.zeros(base.n_faces, dtype=np.int64)
    level = 0.5 * (np.log2(expansion) + np.log2(reference_faces / base.n_faces))
    with np.errstate(divide="ignore"):
        own = level + 0.5 * np.log2(area / mean)        # -inf for a zero-area face: level 0
    # the nearest level, halves rounded up (as C's round does for these non-negative ones)
    levels = np.maximum(np.floor(np.nan_to_num(own, neginf=0.0) + 0.5), 0).astype(np.int64)
    return raised_to_balance(base, levels)

