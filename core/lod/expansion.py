"""The field's default storage: micro-triangles "per input face" counted as micromesh-tools
counts its microexpansion, and the bytes its files would take on disk.

``tessellate -mode uniform -microexpansion e`` (NVlabs/micromesh-tools, the staged tool's
default is e = 2) aims at e times the input's faces with one global level
L = (log2 e + log2(input faces / base faces)) / 2, gives each base face the nearest whole
level to L + log4(its area / the mean area) (0 at least), and then raises levels until
neighbours differ by at most one. Rounding per face and raising make more micro-triangles
than e × input faces: 2.0-2.47 times the input's faces at e = 2 on the shared meshes
(``docs/results.md``). A budget of e "per input face" is the ``.bin`` + ``.bary`` those
levels take in micromesh-tools' files (``core.io.file_size.mmt_file_bytes``) on the base at
hand, and never less than on the base its ``decimate -reduction_fn 32`` aims at
(:func:`nominal_expansion_bytes`, from the input's face count alone); adaptive LOD then places
it by visual gain, counted in our own files' bytes (``core.construct.state.budget_cost``).
"""
from __future__ import annotations

import numpy as np

from ..io.file_size import mmt_file_bytes
from ..mesh.trimesh import TriMesh
from ..micro.levels import raised_to_balance

# micromesh-tools' default decimation target: the input's faces / 32 (``-reduction_fn 32``)
REDUCTION = 32


def _global_level(reference_faces: int, base_faces: int, expansion: float) -> float:
    return 0.5 * (np.log2(expansion) + np.log2(reference_faces / base_faces))


def expansion_levels(base: TriMesh, reference_faces: int, expansion: float) -> np.ndarray:
    """(F,) levels of the uniform tessellation of ``base`` at ``expansion`` micro-triangles
    per reference face, balanced (±1 across edges) by raising."""
    if base.n_faces == 0 or reference_faces <= 0 or expansion <= 0:
        return np.zeros(base.n_faces, dtype=np.int64)
    area = np.asarray(base.face_areas, dtype=np.float64)
    mean = float(area.mean())
    if not mean > 0.0:
        return np.zeros(base.n_faces, dtype=np.int64)
    level = _global_level(reference_faces, base.n_faces, expansion)
    with np.errstate(divide="ignore"):
        own = level + 0.5 * np.log2(area / mean)        # -inf for a zero-area face: level 0
    # the nearest level, halves rounded up (as C's round does for these non-negative ones)
    levels = np.maximum(np.floor(np.nan_to_num(own, neginf=0.0) + 0.5), 0).astype(np.int64)
    return raised_to_balance(base, levels)


def expansion_bytes(base: TriMesh, reference_faces: int, expansion: float) -> int:
    """micromesh-tools' ``.bin`` + ``.bary`` for its uniform tessellation of ``base``."""
    return mmt_file_bytes(expansion_levels(base, reference_faces, expansion), base.n_vertices)


def nominal_expansion_bytes(reference_faces: int, expansion: float) -> int:
    """micromesh-tools' ``.bin`` + ``.bary`` for an input of ``reference_faces`` faces, from
    that count alone: the base its decimation aims at (faces / 32, half as many vertices, a
    closed surface's share) with faces of equal area, all at the nearest level to L. Its
    decimation stops earlier where its error bound binds, and its files then take more: 0.20
    to 0.96 of what it wrote on the shared meshes (``docs/results.md``, thirty-third
    session)."""
    if reference_faces <= 0 or expansion <= 0:
        return 0
    faces = max(reference_faces // REDUCTION, 1)
    level = max(int(np.floor(_global_level(reference_faces, faces, expansion) + 0.5)), 0)
    return mmt_file_bytes(np.full(faces, level), faces // 2 + 2)
